// What the `sls` subcommands share: global options, JSON or human output, exit codes, and
// the guard that turns sls::Error into a message and an exit status.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "samples/sls/progress_display.h"

namespace sls::cli {

// Exit statuses, listed in `sls --help`.
enum ExitCode : int {
  kExitOk = 0,
  kExitError = 1,        // the work failed: the message says why
  kExitUsage = 2,        // bad command line
  kExitUnavailable = 3,  // the feature is not in this build (e.g. CUDA asked of a build without it)
  kExitInterrupted = 4,  // stopped by a signal; what was done is written and valid (sls scan)
};

// Free space an output folder must have before a command starts work in it: a report, a
// trajectory and a model or a frame's depth maps, or the first frames of a capture (a 12 MP
// stack of 22 PNGs is ~300 MB, so a capture may still fill the disk later: it then stops with
// the frames before kept).
constexpr std::uint64_t kFirstOutputsBytes = 64ull << 20;

struct GlobalOptions {
  bool json = false;   // machine-readable JSON on stdout, nothing else there
  bool quiet = false;  // no progress display
  int verbosity = 0;   // -v: info, -vv: debug
};

// The state a subcommand runs with.
struct Context {
  GlobalOptions options;
  // A progress callback drawing on stderr, or empty with --quiet / --json.
  ProgressCallback progress_callback(const std::string& stage) const;
  // Prints `result` as JSON (with --json) or through `human` (without).
  void emit(const nlohmann::json& result, const std::function<void()>& human) const;
  // Called by `sls scan` after each frame it fused, skipped or lost, with the frame's index.
  // The tool leaves it unset; a program running a command in-process (tests/unit/cli) may set
  // it. An exception from it ends the frame loop as a fault of the machine does (sls::Error,
  // or std::bad_alloc as kOutOfMemory): with frames fused, they are written as a partial model.
  std::function<void(int frame)> after_frame;
};

// A number in [lo, hi], or 0 too with zero_allowed ("0: automatic"). NaN and infinities are
// refused, which CLI::Range lets through.
CLI::Validator finite_range(double lo, double hi, bool zero_allowed = false);

// Runs a subcommand body: sls::Error -> message on stderr (and a JSON error object on
// stdout with --json) and the matching exit status. Sets *exit_code.
void run_command(const Context& context, const std::string& name, const std::function<int()>& body, int* exit_code);

}  // namespace sls::cli
