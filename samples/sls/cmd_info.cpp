// sls info: what this build can do and which GPUs it sees.
#include <iostream>

#include "samples/sls/commands.h"
#include "sdk/core/device.h"

namespace sls::cli {

void add_info_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand("info", "Show the build (version, CUDA support) and the GPUs it can use");
  command->callback([&context, exit_code] {
    run_command(context, "info", [&context] {
      nlohmann::json gpus = nlohmann::json::array();
      const int count = cuda_device_count();
      for (int id = 0; id < count; ++id) gpus.push_back({{"id", id}, {"name", cuda_device_name(id)}});
      const nlohmann::json result = {{"version", SLS_VERSION}, {"cuda_compiled", cuda_compiled()}, {"cuda_devices", gpus}};
      context.emit(result, [&] {
        std::cout << "slscan " << SLS_VERSION << "\n"
                  << "CUDA backends: " << (cuda_compiled() ? "compiled in" : "not built") << "\n"
                  << "CUDA devices:  " << count << "\n";
        for (const auto& gpu : gpus) std::cout << "  cuda:" << gpu["id"].get<int>() << "  " << gpu["name"].get<std::string>() << "\n";
      });
      return kExitOk;
    }, exit_code);
  });
}

}  // namespace sls::cli
