// Draws sls::ProgressUpdate on stderr: a redrawn bar on a terminal, one line per 10% when
// stderr is a file or a pipe (logs stay readable).
#pragma once

#include <string>

#include "sdk/core/progress.h"

namespace sls::cli {

ProgressCallback make_progress_display(const std::string& stage);

}  // namespace sls::cli
