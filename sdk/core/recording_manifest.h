// A recording's manifest.json (the format: recording.h), parsed and checked on its own,
// without touching any other file of the recording: what RecordingReader::open reads first,
// and what the manifest fuzz target feeds.
#pragma once

#include <string>
#include <vector>

#include "sdk/core/recording.h"

namespace sls {

namespace manifest {
constexpr const char* kFormatName = "slscan-recording";
constexpr const char* kCalibrationName = "calibration.yml";
constexpr const char* kDepthFormat = "png16";
constexpr int kMaxSide = 1 << 20;  // of a camera image
}  // namespace manifest

struct RecordingManifest {
  RecordingInfo info;
  std::vector<FrameInfo> frames;     // frame indices strictly increasing
  std::string groundtruth_relative;  // empty when the recording has no ground truth
  std::string calibration_relative;  // empty when recorded uncalibrated
};

// Parses a manifest's text; `path` names the file in errors. Every path in the result is
// relative and stays inside the recording folder. Throws sls::Error naming the file: kFormat
// (invalid JSON with its byte position, missing or mistyped keys, values out of range, paths
// leaving the folder), kVersionMismatch (format_version newer than this SDK reads).
RecordingManifest parse_recording_manifest(const std::string& text, const std::string& path);

}  // namespace sls
