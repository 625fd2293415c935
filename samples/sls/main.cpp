// sls: the slscan command-line tool.
#include <iostream>

#include <spdlog/spdlog.h>

#include "samples/sls/commands.h"

int main(int argc, char** argv) {
  using namespace sls::cli;
  CLI::App app{"sls: structured-light scanning and high-resolution fusion (slscan)", "sls"};
  app.set_version_flag("--version", std::string("sls ") + SLS_VERSION);
  app.require_subcommand(1);
  // The global options below are accepted after the command too (`sls eval ... --json`): a
  // command passes the options it does not know to sls. Inherited by every command added after.
  app.fallthrough();
  app.footer(
      "Run `sls COMMAND --help` for a command's options.\n"
      "Devices are named by URI (sim://, gige://, usb3://, dlpc350://, headctl://): `sls devices` lists them;\n"
      "replay://RECORDING plays a recording back as camera, projector and turntable.\n"
      "Exit status: 0 ok, 1 the work failed (the message says why), 2 bad command line,\n"
      "3 the feature is not available in this build (e.g. CUDA asked of a build without it),\n"
      "4 interrupted (SIGINT/SIGTERM): what was done so far is written and valid.");

  Context context;
  app.add_flag("--json", context.options.json, "Print machine-readable JSON on stdout (and nothing else there)");
  app.add_flag("-q,--quiet", context.options.quiet, "No progress display");
  app.add_flag("-v,--verbose", context.options.verbosity, "More log output (-vv for debug)");

  int exit_code = kExitOk;
  add_bench_command(app, context, &exit_code);
  add_calibrate_command(app, context, &exit_code);
  add_decode_command(app, context, &exit_code);
  add_devices_command(app, context, &exit_code);
  add_eval_command(app, context, &exit_code);
  add_import_command(app, context, &exit_code);
  add_info_command(app, context, &exit_code);
  add_inspect_command(app, context, &exit_code);
  add_scan_command(app, context, &exit_code);
  add_sim_command(app, context, &exit_code);

  app.parse_complete_callback([&context] {
    spdlog::set_level(context.options.verbosity >= 2   ? spdlog::level::debug
                      : context.options.verbosity == 1 ? spdlog::level::info
                                                       : spdlog::level::warn);
  });
  // The first word that is not a global option names the command: say so when it names none
  // (CLI11 alone would say "A subcommand is required").
  for (int i = 1; i < argc; ++i) {
    const std::string word = argv[i];
    if (!word.empty() && word[0] == '-') continue;
    std::string known;
    bool found = false;
    for (const CLI::App* command : app.get_subcommands({})) {
      known += (known.empty() ? "" : ", ") + command->get_name();
      found = found || command->get_name() == word;
    }
    if (!found) {
      std::cerr << "sls: unknown command '" << word << "' (commands: " << known << "; sls --help)\n";
      return kExitUsage;
    }
    break;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    const int status = app.exit(error);
    return status == 0 ? kExitOk : kExitUsage;
  }
  return exit_code;
}
