// The whole calibration of a capture on disk, as `sls calibrate` runs it: every view read,
// its board found, its patterns decoded and its corners located in the projector, then the
// solve (camera, projector, joint refinement, turntable axis). One iteration is one
// calibration; the counters give each stage's share (seconds, summed over views).
//   SLS_CALIBRATION_CAPTURE=/path/to/capture bench_calibrate
// (a recording from `sls sim --calibration --preset paper` for the 4000 x 3000 figure;
// SLS_CALIBRATION_PATTERNS and SLS_CALIBRATION_BOARD=COLSxROWSxSQUARE_M for a folder of
// captures, e.g. opencv-graycode:1024x768 and 9x7x0.075 for shared/data/procam-calibration).
#include <cstdio>
#include <cstdlib>
#include <string>

#include <benchmark/benchmark.h>

#include "calib/calibrate_capture.h"

namespace {

void BM_CalibrateCapture(benchmark::State& state) {
  const char* capture = std::getenv("SLS_CALIBRATION_CAPTURE");
  if (capture == nullptr) {
    state.SkipWithError("set SLS_CALIBRATION_CAPTURE to a calibration capture (see the file's comment)");
    return;
  }
  sls::calib::CalibrateCaptureOptions options;
  options.input = capture;
  if (const char* patterns = std::getenv("SLS_CALIBRATION_PATTERNS")) options.patterns = patterns;
  if (const char* board = std::getenv("SLS_CALIBRATION_BOARD")) {
    if (std::sscanf(board, "%dx%dx%lf", &options.board.inner_cols, &options.board.inner_rows,
                    &options.board.square_m) != 3) {
      state.SkipWithError("SLS_CALIBRATION_BOARD: expected COLSxROWSxSQUARE_M");
      return;
    }
  }
  sls::calib::CalibrateCaptureResult result;
  for (auto _ : state) {
    result = sls::calib::calibrate_capture(options, {});
    // No DoNotOptimize: the result feeds the counters (and Debian's benchmark 1.7's
    // DoNotOptimize on a double member clobbered it here).
  }
  state.counters["views"] = static_cast<double>(result.views.size());
  state.counters["views_used"] = result.procam.views_used;
  state.counters["load_s"] = result.load_s;
  state.counters["detect_s"] = result.detect_s;
  state.counters["decode_s"] = result.decode_s;
  state.counters["homography_s"] = result.homography_s;
  state.counters["solve_s"] = result.solve_s;
  state.counters["stereo_rms_px"] = result.procam.stereo_rms_px;
}
BENCHMARK(BM_CalibrateCapture)->Unit(benchmark::kSecond)->Iterations(1)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
