// libFuzzer target: calibration files (OpenCV FileStorage YAML; an OpenCV XML file among the
// seeds must be refused cleanly). Whatever is accepted validates.
#include <string>

#include "sdk/core/calibration.h"
#include "sdk/core/error.h"
#include "tests/fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  sls::ScannerCalibration calibration;
  try {
    calibration = sls::parse_calibration(sls::fuzz::as_text(data, size), "calibration.yml");
  } catch (const sls::Error&) {
    return 0;
  }
  calibration.validate();  // an sls::Error here escapes: accepted calibrations are valid
  return 0;
}
