// libFuzzer target: a recording's manifest.json. Whatever is accepted has sizes in range,
// strictly increasing frame indices, the image count the header promises, capture counters in
// range, and only relative paths that stay inside the recording.
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>

#include "sdk/core/error.h"
#include "sdk/core/recording_manifest.h"
#include "tests/fuzz/fuzz_support.h"

using sls::fuzz::check;

namespace {

void check_inside(const std::string& relative) {
  const std::filesystem::path path(relative);
  check(!relative.empty() && !path.has_root_path());
  for (const std::filesystem::path& part : path) check(part != "..");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  sls::RecordingManifest manifest;
  try {
    manifest = sls::parse_recording_manifest(sls::fuzz::as_text(data, size), "manifest.json");
  } catch (const sls::Error&) {
    return 0;
  }
  const sls::RecordingInfo& info = manifest.info;
  check(info.camera.width >= 1 && info.camera.height >= 1 && info.camera.bit_depth >= 1 && info.camera.bit_depth <= 16);
  check(info.images_per_frame >= 0 && info.depth_unit_m > 0.0 && info.depth_offset_m >= 0.0);
  for (std::size_t i = 0; i < manifest.frames.size(); ++i) {
    const sls::FrameInfo& frame = manifest.frames[i];
    check(frame.index >= 0 && (i == 0 || frame.index > manifest.frames[i - 1].index));
    check(frame.image_files.size() <= static_cast<std::size_t>(info.images_per_frame));
    check(!frame.complete || frame.image_files.size() == static_cast<std::size_t>(info.images_per_frame));
    for (const std::string& file : frame.image_files) check_inside(file);
    if (frame.has_depth()) check_inside(frame.depth_file);
    if (frame.capture) {
      const sls::FrameCaptureCounters& capture = *frame.capture;
      check(capture.attempts >= 1 && capture.incomplete_images >= 0 && capture.lost_images >= 0 &&
            capture.stale_images >= 0);
      constexpr std::uint64_t kMaxPackets = std::numeric_limits<std::int64_t>::max();
      check(!capture.transport || (capture.transport->resent_packets <= kMaxPackets &&
                                   capture.transport->missing_packets <= kMaxPackets &&
                                   capture.transport->queue_depth <= kMaxPackets));
    }
  }
  if (info.has_groundtruth) check_inside(manifest.groundtruth_relative);
  if (!manifest.calibration_relative.empty()) check_inside(manifest.calibration_relative);
  return 0;
}
