// One function per `sls` subcommand, each in its own cmd_<name>.cpp. A subcommand adds its
// options to `app` and sets a callback that runs through cli::run_command.
#pragma once

#include <CLI/CLI.hpp>

#include "samples/sls/cli.h"

namespace sls::cli {

void add_bench_command(CLI::App& app, Context& context, int* exit_code);
void add_calibrate_command(CLI::App& app, Context& context, int* exit_code);
void add_decode_command(CLI::App& app, Context& context, int* exit_code);
void add_devices_command(CLI::App& app, Context& context, int* exit_code);
void add_eval_command(CLI::App& app, Context& context, int* exit_code);
void add_import_command(CLI::App& app, Context& context, int* exit_code);
void add_info_command(CLI::App& app, Context& context, int* exit_code);
void add_inspect_command(CLI::App& app, Context& context, int* exit_code);
void add_scan_command(CLI::App& app, Context& context, int* exit_code);
void add_sim_command(CLI::App& app, Context& context, int* exit_code);

}  // namespace sls::cli
