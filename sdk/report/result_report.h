// report.html of a result folder, for whoever has one but did not run `sls scan` (which
// writes its report itself): an integrator who scanned through the C API and wrote the model
// and trajectory there (sls_report_write_html), or a result re-read later. Reads
// RESULT/cloud.ply and, when they are there, RESULT/report.json (a scan's summary),
// trajectory.txt and undeformed/trajectory.txt (online deformation's poses as tracked); with
// a simulated recording, measures the result against its ground truth first (as `sls eval`,
// the model as tracked too) for the quality table, the heat map and the true trajectory.
#pragma once

#include <string>

#include "sdk/core/progress.h"
#include "sdk/report/scan_report.h"

namespace sls::report {

struct ResultReportOptions {
  std::string recording_folder;  // a simulated recording with ground truth; empty: none
  double voxel_size_m = 0.0;     // for measuring against it; 0: RESULT/report.json's
  std::string title;             // empty: "Scan of RESULT"
  int image_size_px = 800;       // longer side of each render, 64 to 4096
};

// Writes RESULT/report.html and its PNGs (write_scan_report_html). sls::Error naming the file:
// kNotFound (no RESULT/cloud.ply, no recording), kFormat (a corrupt cloud, report.json or
// trajectory), kInvalidArgument (a recording without ground truth, a bad option), kIo (RESULT
// not writable); evaluate_result()'s errors with a recording. Nothing is written on an error.
ScanReportFiles write_result_report_html(const std::string& result_folder, const ResultReportOptions& options = {},
                                         const ProgressCallback& progress = {});

}  // namespace sls::report
