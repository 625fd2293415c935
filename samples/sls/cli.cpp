#include "samples/sls/cli.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include <fmt/format.h>

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

CLI::Validator finite_range(double lo, double hi, bool zero_allowed) {
  const std::string description = fmt::format("{}{:g} .. {:g}", zero_allowed ? "0 or " : "", lo, hi);
  return CLI::Validator(
      [lo, hi, zero_allowed, description](std::string& text) {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        const bool ok = end != text.c_str() && *end == '\0' && std::isfinite(value) &&
                        ((zero_allowed && value == 0.0) || (value >= lo && value <= hi));
        return ok ? std::string() : fmt::format("{} is not a number in {}", text.substr(0, 40), description);
      },
      description);
}

}  // namespace sls::cli
