#include "samples/sls/cli.h"

#include <cstdio>
#include <iostream>

#include "sdk/core/error.h"

namespace sls::cli {

ProgressCallback Context::progress_callback(const std::string& stage) const {
  if (options.quiet || options.json) return {};
  return make_progress_display(stage);
}

void Context::emit(const nlohmann::json& result, const std::function<void()>& human) const {
  if (options.json) {
    std::cout << result.dump(2) << std::endl;
  } else {
    human();
  }
}

void run_command(const Context& context, const std::string& name, const std::function<int()>& body, int* exit_code) {
  try {
    *exit_code = body();
    return;
  } catch (const sls::Error& error) {
    *exit_code = error.code() == ErrorCode::kUnsupported ? kExitUnavailable : kExitError;
    std::cerr << "sls " << name << ": error: " << error.what() << std::endl;
    if (context.options.json) {
      nlohmann::json out = {{"ok", false},
                            {"command", name},
                            {"status", static_cast<int>(error.code())},
                            {"status_name", error_code_name(error.code())},
                            {"message", error.what()}};
      std::cout << out.dump(2) << std::endl;
    }
  } catch (const std::exception& error) {
    *exit_code = kExitError;
    std::cerr << "sls " << name << ": internal error: " << error.what() << std::endl;
  }
}

}  // namespace sls::cli
