#include "sdk/core/recording_manifest.h"

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <utility>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sdk/core/error.h"

namespace sls {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;
using namespace manifest;

// Every accessor names the file and the key path in its error.
class ManifestParser {
 public:
  explicit ManifestParser(std::string path) : path_(std::move(path)) {}

  [[noreturn]] void fail(const std::string& what) const {
    throw_error(ErrorCode::kFormat, "{}: {}", path_, what);
  }

  const Json& member(const Json& object, const char* key, const std::string& where) const {
    const auto it = object.find(key);
    if (it == object.end()) fail(fmt::format("missing key '{}'", join(where, key)));
    return *it;
  }
  const Json* optional_member(const Json& object, const char* key) const {
    const auto it = object.find(key);
    return it == object.end() || it->is_null() ? nullptr : &*it;
  }
  const Json& object(const Json& parent, const char* key, const std::string& where) const {
    const Json& value = member(parent, key, where);
    if (!value.is_object()) fail(fmt::format("'{}' must be an object, not {}", join(where, key), value.type_name()));
    return value;
  }
  std::string string(const Json& value, const std::string& name) const {
    if (!value.is_string()) fail(fmt::format("'{}' must be a string, not {}", name, value.type_name()));
    return value.get<std::string>();
  }
  std::string string(const Json& parent, const char* key, const std::string& where) const {
    return string(member(parent, key, where), join(where, key));
  }
  std::int64_t integer(const Json& parent, const char* key, const std::string& where, std::int64_t min,
                       std::int64_t max) const {
    const Json& value = member(parent, key, where);
    const std::string name = join(where, key);
    if (!value.is_number_integer()) fail(fmt::format("'{}' must be an integer, not {}", name, value.type_name()));
    if (value.is_number_unsigned() && value.get<std::uint64_t>() > static_cast<std::uint64_t>(max)) {
      fail(fmt::format("'{}' = {} is outside {}..{}", name, value.get<std::uint64_t>(), min, max));
    }
    const auto number = value.get<std::int64_t>();
    if (number < min || number > max) fail(fmt::format("'{}' = {} is outside {}..{}", name, number, min, max));
    return number;
  }
  double number(const Json& value, const std::string& name) const {
    if (!value.is_number()) fail(fmt::format("'{}' must be a number, not {}", name, value.type_name()));
    return value.get<double>();
  }
  // A path inside the recording folder: relative, no "..", no root.
  std::string relative_path(const Json& value, const std::string& name) const {
    const std::string text = string(value, name);
    const fs::path path(text);
    if (text.empty()) fail(fmt::format("'{}' is an empty path", name));
    if (path.has_root_path()) fail(fmt::format("'{}' = \"{}\" is absolute; paths must stay inside the recording", name, text));
    for (const fs::path& part : path) {
      if (part == "..") fail(fmt::format("'{}' = \"{}\" leaves the recording folder", name, text));
    }
    return text;
  }

  static std::string join(const std::string& where, const char* key) {
    return where.empty() ? std::string(key) : where + "." + key;
  }

 private:
  std::string path_;
};

// A frame's optional "capture" counters (the capture sequencer's): every count an integer in
// range; the transport's three keys all or none.
FrameCaptureCounters parse_capture(const ManifestParser& parser, const Json& json, const std::string& where) {
  if (!json.is_object()) parser.fail(fmt::format("'{}' must be an object, not {}", where, json.type_name()));
  constexpr std::int64_t kMaxCount = std::numeric_limits<int>::max();
  constexpr std::int64_t kMaxPackets = std::numeric_limits<std::int64_t>::max();
  FrameCaptureCounters capture;
  capture.attempts = static_cast<int>(parser.integer(json, "attempts", where, 1, kMaxCount));
  capture.incomplete_images = static_cast<int>(parser.integer(json, "incomplete_images", where, 0, kMaxCount));
  capture.lost_images = static_cast<int>(parser.integer(json, "lost_images", where, 0, kMaxCount));
  capture.stale_images = static_cast<int>(parser.integer(json, "stale_images", where, 0, kMaxCount));
  static const char* const kTransportKeys[] = {"resent_packets", "missing_packets", "queue_depth"};
  std::size_t present = 0;
  for (const char* key : kTransportKeys) present += json.contains(key) ? 1u : 0u;
  if (present > 0) {
    FrameTransportCounters transport;
    transport.resent_packets = static_cast<std::uint64_t>(parser.integer(json, "resent_packets", where, 0, kMaxPackets));
    transport.missing_packets =
        static_cast<std::uint64_t>(parser.integer(json, "missing_packets", where, 0, kMaxPackets));
    transport.queue_depth = static_cast<std::uint64_t>(parser.integer(json, "queue_depth", where, 0, kMaxPackets));
    capture.transport = transport;
  }
  return capture;
}

FrameInfo parse_frame(const ManifestParser& parser, const Json& json, std::size_t position, int images_per_frame) {
  const std::string where = fmt::format("frames[{}]", position);
  if (!json.is_object()) parser.fail(fmt::format("'{}' must be an object, not {}", where, json.type_name()));
  FrameInfo frame;
  frame.index = static_cast<int>(parser.integer(json, "index", where, 0, std::numeric_limits<int>::max()));
  frame.timestamp_ns = parser.integer(json, "timestamp_ns", where, std::numeric_limits<std::int64_t>::min(),
                                      std::numeric_limits<std::int64_t>::max());
  if (const Json* angle = parser.optional_member(json, "turntable_angle_deg")) {
    frame.turntable_angle_deg = parser.number(*angle, where + ".turntable_angle_deg");
  }
  const std::string status = parser.string(json, "status", where);
  if (status != "complete" && status != "incomplete") {
    parser.fail(fmt::format("'{}.status' = \"{}\" must be \"complete\" or \"incomplete\"", where, status));
  }
  frame.complete = status == "complete";
  if (const Json* note = parser.optional_member(json, "note")) frame.note = parser.string(*note, where + ".note");
  if (const Json* capture = parser.optional_member(json, "capture")) {
    frame.capture = parse_capture(parser, *capture, where + ".capture");
  }
  const Json& images = parser.member(json, "images", where);
  if (!images.is_array()) parser.fail(fmt::format("'{}.images' must be an array, not {}", where, images.type_name()));
  const std::size_t expected = static_cast<std::size_t>(images_per_frame);
  if (frame.complete ? images.size() != expected : images.size() > expected) {
    parser.fail(fmt::format("'{}.images' lists {} images; images_per_frame is {}{}", where, images.size(),
                            images_per_frame, frame.complete ? "" : " (an incomplete frame may have fewer, not more)"));
  }
  for (std::size_t k = 0; k < images.size(); ++k) {
    frame.image_files.push_back(parser.relative_path(images[k], fmt::format("{}.images[{}]", where, k)));
  }
  if (const Json* depth = parser.optional_member(json, "depth")) {
    frame.depth_file = parser.relative_path(*depth, where + ".depth");
  }
  if (images_per_frame == 0 && frame.depth_file.empty()) {
    parser.fail(fmt::format("'{}' has no depth map, but the recording is depth-only (images_per_frame 0)", where));
  }
  return frame;
}

}  // namespace

RecordingManifest parse_recording_manifest(const std::string& text, const std::string& path) {
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::parse_error& parse_error) {
    throw_error(ErrorCode::kFormat, "{}: corrupt manifest, invalid JSON at byte {}{}: {}", path, parse_error.byte,
                parse_error.byte > text.size() ? fmt::format(" (the file ends at byte {}: truncated?)", text.size())
                                               : std::string(),
                parse_error.what());
  } catch (const Json::exception& error) {
    // The JSON is well formed but holds what nlohmann cannot store: a number beyond a double
    // (out_of_range 406, e.g. 1e999).
    throw_error(ErrorCode::kFormat, "{}: corrupt manifest: {}", path, error.what());
  }
  const ManifestParser parser(path);
  if (!root.is_object()) parser.fail(fmt::format("the manifest must be a JSON object, not {}", root.type_name()));
  const std::string format = parser.string(root, "format", "");
  if (format != kFormatName) parser.fail(fmt::format("format is \"{}\", not \"{}\"", format, kFormatName));
  const std::int64_t version = parser.integer(root, "format_version", "", 1, std::numeric_limits<int>::max());
  if (version > RecordingInfo::kFormatVersion) {
    throw_error(ErrorCode::kVersionMismatch,
                "{}: recording format_version {} is newer than this SDK reads (up to {}); update slscan", path,
                version, RecordingInfo::kFormatVersion);
  }

  RecordingManifest parsed;
  RecordingInfo& info = parsed.info;
  info.created_utc = parser.string(root, "created_utc", "");
  const Json& device = parser.object(root, "device", "");
  info.device.uri = parser.string(device, "uri", "device");
  info.device.model = parser.string(device, "model", "device");
  info.device.serial = parser.string(device, "serial", "device");
  const Json& camera = parser.object(root, "camera", "");
  info.camera.width = static_cast<int>(parser.integer(camera, "width", "camera", 1, kMaxSide));
  info.camera.height = static_cast<int>(parser.integer(camera, "height", "camera", 1, kMaxSide));
  info.camera.bit_depth = static_cast<int>(parser.integer(camera, "bit_depth", "camera", 1, 16));
  info.pattern_set_json = parser.object(root, "pattern_set", "").dump();
  info.images_per_frame =
      static_cast<int>(parser.integer(root, "images_per_frame", "", 0, std::numeric_limits<int>::max()));
  if (const Json* exposures = parser.optional_member(root, "exposures")) {
    if (!exposures->is_array() || exposures->empty() || exposures->size() > 4) {
      parser.fail("'exposures' must be an array of 1 to 4 exposure scales");
    }
    for (std::size_t i = 0; i < exposures->size(); ++i) {
      const double scale = parser.number((*exposures)[i], fmt::format("exposures[{}]", i));
      if (!(std::isfinite(scale) && scale > 0.0)) parser.fail(fmt::format("exposures[{}] must be positive", i));
      info.exposures.push_back(scale);
    }
    if (info.images_per_frame % static_cast<int>(info.exposures.size()) != 0) {
      parser.fail(fmt::format("images_per_frame {} is not a whole stack per exposure ({} exposures)",
                              info.images_per_frame, info.exposures.size()));
    }
  }
  if (const Json* encoding = parser.optional_member(root, "depth_encoding")) {
    if (!encoding->is_object()) parser.fail("'depth_encoding' must be an object");
    const std::string depth_format = parser.string(*encoding, "format", "depth_encoding");
    if (depth_format != kDepthFormat) {
      parser.fail(fmt::format("depth_encoding.format \"{}\" is not supported (only \"{}\")", depth_format, kDepthFormat));
    }
    info.depth_unit_m = parser.number(parser.member(*encoding, "unit_m", "depth_encoding"), "depth_encoding.unit_m");
    info.depth_offset_m =
        parser.number(parser.member(*encoding, "offset_m", "depth_encoding"), "depth_encoding.offset_m");
    if (!(info.depth_unit_m > 0.0) || !(info.depth_offset_m >= 0.0)) {
      parser.fail("depth_encoding needs unit_m > 0 and offset_m >= 0");
    }
  }
  if (const Json* groundtruth = parser.optional_member(root, "groundtruth")) {
    parsed.groundtruth_relative = parser.relative_path(*groundtruth, "groundtruth");
    info.has_groundtruth = true;
  }

  const Json& frames = parser.member(root, "frames", "");
  if (!frames.is_array()) parser.fail(fmt::format("'frames' must be an array, not {}", frames.type_name()));
  parsed.frames.reserve(frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    FrameInfo frame = parse_frame(parser, frames[i], i, info.images_per_frame);
    if (!parsed.frames.empty() && frame.index <= parsed.frames.back().index) {
      parser.fail(fmt::format("frames[{}].index {} does not increase (previous {})", i, frame.index,
                              parsed.frames.back().index));
    }
    parsed.frames.push_back(std::move(frame));
  }

  // Calibration: a missing key means the default name (every recording written by this SDK
  // has the key); null means recorded uncalibrated.
  parsed.calibration_relative = kCalibrationName;
  const auto calibration = root.find("calibration");
  if (calibration != root.end()) {
    parsed.calibration_relative =
        calibration->is_null() ? std::string() : parser.relative_path(*calibration, "calibration");
  }
  return parsed;
}

}  // namespace sls
