#include "sdk/core/recording.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <algorithm>
#include <cstdint>
#include <ctime>
#include <filesystem>
#include <limits>
#include <utility>

#include <nlohmann/json.hpp>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/log.h"
#include "sdk/core/host_memory.h"
#include "sdk/core/image_io.h"
#include "sdk/core/recording_manifest.h"
#include "sdk/core/run_parallel.h"

namespace sls {
namespace {

namespace fs = std::filesystem;
// ordered_json keeps "format" first and the caller's pattern-set key order: easier to read.
using Json = nlohmann::ordered_json;

using manifest::kFormatName;
constexpr const char* kManifestName = "manifest.json";
using manifest::kCalibrationName;
constexpr const char* kGroundtruthName = "groundtruth";
constexpr const char* kFramesName = "frames";
using manifest::kDepthFormat;
using manifest::kMaxSide;

std::string absolute_folder(const std::string& folder) {
  if (folder.empty()) throw_error(ErrorCode::kInvalidArgument, "recording folder path is empty");
  fs::path path = fs::absolute(fs::path(folder)).lexically_normal();
  std::string text = path.string();
  while (text.size() > 1 && text.back() == '/') text.pop_back();
  return text;
}

std::string utc_now_iso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32] = {};
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

std::string frame_folder_relative(int index) { return fmt::format("{}/{:06d}", kFramesName, index); }

// Writes a file in place and fsyncs it. Frame files need no rename: the manifest lists them
// only after they are complete, and a stray half file is never read.
void write_file_synced(const std::string& path, const std::vector<std::uint8_t>& bytes, bool sync) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(ErrorCode::kIo, "cannot create " + describe_errno(path, errno));
  std::size_t written = 0;
  int error_number = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      error_number = errno;
      break;
    }
    written += static_cast<std::size_t>(n);
  }
  if (error_number == 0 && sync && ::fsync(fd) != 0) error_number = errno;
  if (::close(fd) != 0 && error_number == 0) error_number = errno;
  if (error_number != 0) throw Error(ErrorCode::kIo, "cannot write " + describe_errno(path, error_number));
}

// Depth steps on disk <-> metres in memory (see recording.h).
Image16u depth_to_steps(const Image32f& depth_m, double unit_m, double offset_m, std::size_t* out_of_range) {
  Image16u steps(depth_m.width(), depth_m.height());
  const float* in = depth_m.data();
  std::uint16_t* out = steps.data();
  for (std::size_t i = 0; i < depth_m.pixel_count(); ++i) {
    const float d = in[i];
    if (!std::isfinite(d) || d <= 0.0f) continue;  // invalid stays 0
    const double step = std::round((static_cast<double>(d) - offset_m) / unit_m);
    if (step < 1.0 || step > 65535.0) {
      ++*out_of_range;
      continue;
    }
    out[i] = static_cast<std::uint16_t>(step);
  }
  return steps;
}

Image32f steps_to_depth(const Image16u& steps, double unit_m, double offset_m) {
  Image32f depth(steps.width(), steps.height());
  const std::uint16_t* in = steps.data();
  float* out = depth.data();
  for (std::size_t i = 0; i < steps.pixel_count(); ++i) {
    if (in[i] != 0) out[i] = static_cast<float>(offset_m + static_cast<double>(in[i]) * unit_m);
  }
  return depth;
}

std::string normalised_pattern_set(const std::string& text, const std::string& folder) {
  Json parsed;
  try {
    parsed = Json::parse(text);
  } catch (const Json::parse_error& error) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: pattern_set_json is not valid JSON (byte {}): {}", folder,
                error.byte, error.what());
  }
  if (!parsed.is_object()) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: pattern_set_json must be a JSON object, got {}", folder,
                parsed.type_name());
  }
  return parsed.dump();
}

void validate_info(const RecordingInfo& info, const std::string& folder) {
  const RecordingCamera& camera = info.camera;
  if (camera.width <= 0 || camera.height <= 0 || camera.width > kMaxSide || camera.height > kMaxSide) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: camera size {}x{} is invalid", folder, camera.width, camera.height);
  }
  if (camera.bit_depth < 1 || camera.bit_depth > 16) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: camera bit depth {} is outside 1..16", folder, camera.bit_depth);
  }
  // 0 images per frame: a depth-only recording (every frame carries a depth map instead).
  if (info.images_per_frame < 0) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: images_per_frame {} is negative", folder,
                info.images_per_frame);
  }
  if (!info.exposures.empty()) {
    if (info.exposures.size() > 4 || info.images_per_frame <= 0 ||
        info.images_per_frame % static_cast<int>(info.exposures.size()) != 0) {
      throw_error(ErrorCode::kInvalidArgument,
                  "recording {}: {} exposures with {} images per frame (1..4 exposures, each a whole pattern stack)",
                  folder, info.exposures.size(), info.images_per_frame);
    }
    for (const double scale : info.exposures) {
      if (!(std::isfinite(scale) && scale > 0.0)) {
        throw_error(ErrorCode::kInvalidArgument, "recording {}: exposure scale {} must be finite and positive", folder,
                    scale);
      }
    }
  }
  if (!(std::isfinite(info.depth_unit_m) && info.depth_unit_m > 0.0) ||
      !(std::isfinite(info.depth_offset_m) && info.depth_offset_m >= 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: depth unit {} m / offset {} m is invalid (unit > 0, offset >= 0)",
                folder, info.depth_unit_m, info.depth_offset_m);
  }
}

Json frame_to_json(const FrameInfo& frame) {
  Json json;
  json["index"] = frame.index;
  json["timestamp_ns"] = frame.timestamp_ns;
  json["turntable_angle_deg"] = frame.turntable_angle_deg ? Json(*frame.turntable_angle_deg) : Json(nullptr);
  json["images"] = frame.image_files;
  if (frame.has_depth()) json["depth"] = frame.depth_file;
  json["status"] = frame.complete ? "complete" : "incomplete";
  if (!frame.note.empty()) json["note"] = frame.note;
  if (frame.capture) {
    const FrameCaptureCounters& capture = *frame.capture;
    Json counters;
    counters["attempts"] = capture.attempts;
    counters["incomplete_images"] = capture.incomplete_images;
    counters["lost_images"] = capture.lost_images;
    counters["stale_images"] = capture.stale_images;
    if (capture.transport) {
      counters["resent_packets"] = capture.transport->resent_packets;
      counters["missing_packets"] = capture.transport->missing_packets;
      counters["queue_depth"] = capture.transport->queue_depth;
    }
    json["capture"] = std::move(counters);
  }
  return json;
}

// What the manifest parser accepts back (recording_manifest.cpp).
void check_capture_counters(const std::string& folder, const FrameCaptureCounters& capture) {
  constexpr std::uint64_t kMaxPackets = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  const bool packets_fit = !capture.transport || (capture.transport->resent_packets <= kMaxPackets &&
                                                  capture.transport->missing_packets <= kMaxPackets &&
                                                  capture.transport->queue_depth <= kMaxPackets);
  if (capture.attempts < 1 || capture.incomplete_images < 0 || capture.lost_images < 0 || capture.stale_images < 0 ||
      !packets_fit) {
    throw_error(ErrorCode::kInvalidArgument,
                "recording {}: capture counters out of range (attempts {} must be >= 1, image counts {}, {}, {} "
                ">= 0, packet counts < 2^63)",
                folder, capture.attempts, capture.incomplete_images, capture.lost_images, capture.stale_images);
  }
}

}  // namespace

bool operator==(const FrameTransportCounters& a, const FrameTransportCounters& b) {
  return a.resent_packets == b.resent_packets && a.missing_packets == b.missing_packets &&
         a.queue_depth == b.queue_depth;
}

bool operator==(const FrameCaptureCounters& a, const FrameCaptureCounters& b) {
  return a.attempts == b.attempts && a.incomplete_images == b.incomplete_images && a.lost_images == b.lost_images &&
         a.stale_images == b.stale_images && a.transport == b.transport;
}

// ---------------------------------------------------------------------------------------
// Writer

RecordingWriter RecordingWriter::create(const std::string& folder, const RecordingInfo& info,
                                        const std::optional<ScannerCalibration>& calibration,
                                        const RecordingWriterOptions& options) {
  validate_info(info, folder);
  if (options.png_compression_level < 0 || options.png_compression_level > 9) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: PNG compression level {} is outside 0..9", folder,
                options.png_compression_level);
  }
  if (calibration &&
      (calibration->camera.width != info.camera.width || calibration->camera.height != info.camera.height)) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: the calibration is for a {}x{} camera, the recording is {}x{}",
                folder, calibration->camera.width, calibration->camera.height, info.camera.width, info.camera.height);
  }
  // Everything is checked before anything is created, so a refused call leaves no folder.
  if (calibration) calibration->validate();
  RecordingWriter writer;
  writer.folder_ = absolute_folder(folder);
  writer.info_ = info;
  writer.info_.pattern_set_json = normalised_pattern_set(info.pattern_set_json, folder);
  writer.info_.created_utc = utc_now_iso8601();
  writer.has_calibration_ = calibration.has_value();
  writer.options_ = options;

  std::error_code error;
  const fs::file_status status = fs::status(writer.folder_, error);
  if (fs::exists(status)) {
    if (!fs::is_directory(status)) {
      throw_error(ErrorCode::kInvalidArgument, "recording {}: exists and is not a folder", writer.folder_);
    }
    if (!fs::is_empty(writer.folder_, error) || error) {
      throw_error(ErrorCode::kInvalidArgument,
                  "recording {}: the folder exists and is not empty; refusing to write a recording into it",
                  writer.folder_);
    }
  }
  create_directories(writer.folder_);
  create_directories(writer.folder_ + "/" + kFramesName);
  if (info.has_groundtruth) create_directories(writer.folder_ + "/" + kGroundtruthName);
  if (calibration) write_calibration(writer.folder_ + "/" + kCalibrationName, *calibration);
  writer.write_manifest();
  sync_directory(writer.folder_);
  const fs::path parent = fs::path(writer.folder_).parent_path();
  if (!parent.empty()) sync_directory(parent.string());
  return writer;
}

RecordingWriter RecordingWriter::append_to(const std::string& folder, const RecordingWriterOptions& options) {
  if (options.png_compression_level < 0 || options.png_compression_level > 9) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: PNG compression level {} is outside 0..9", folder,
                options.png_compression_level);
  }
  const RecordingReader reader = RecordingReader::open(folder);
  RecordingWriter writer;
  writer.folder_ = reader.folder();
  writer.info_ = reader.info();
  writer.has_calibration_ = reader.has_calibration();
  writer.options_ = options;
  // The manifest is rewritten with the names this writer gives: a recording that names its
  // calibration or ground truth otherwise would silently change meaning.
  const Json root = Json::parse(read_file_text(writer.folder_ + "/" + kManifestName));
  const auto calibration = root.find("calibration");
  if (calibration != root.end() && !calibration->is_null() && *calibration != kCalibrationName) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: its calibration is {}, not {}; cannot append to it",
                writer.folder_, calibration->dump(), kCalibrationName);
  }
  if (writer.info_.has_groundtruth && root.at("groundtruth") != kGroundtruthName) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: its ground truth is {}, not {}; cannot append to it",
                writer.folder_, root.at("groundtruth").dump(), kGroundtruthName);
  }
  for (std::size_t i = 0; i < reader.frame_count(); ++i) {
    // Appending numbers frames by position, as create() did.
    if (reader.frame(i).index != static_cast<int>(i)) {
      throw_error(ErrorCode::kInvalidArgument,
                  "recording {}: frames[{}] has index {}; appending needs frames numbered 0..{} in order",
                  writer.folder_, i, reader.frame(i).index, reader.frame_count() - 1);
    }
    writer.frames_.push_back(reader.frame(i));
  }
  // Temporaries of write_file_atomic (NAME.tmp-PID) that the run cut off left behind: never
  // read, but the recording is to be as an uninterrupted run leaves it.
  std::error_code error;
  for (fs::recursive_directory_iterator it(writer.folder_, error), end; !error && it != end; it.increment(error)) {
    const std::string name = it->path().filename().string();
    if (name.find(".tmp-") != std::string::npos && it->is_regular_file(error)) fs::remove(it->path(), error);
  }
  create_directories(writer.folder_ + "/" + kFramesName);
  return writer;
}

const FrameInfo& RecordingWriter::frame(std::size_t position) const {
  if (position >= frames_.size()) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: frame {} does not exist ({} frames)", folder_, position,
                frames_.size());
  }
  return frames_[position];
}

std::string RecordingWriter::groundtruth_folder() const {
  return info_.has_groundtruth ? folder_ + "/" + kGroundtruthName : std::string();
}

void RecordingWriter::close() { closed_ = true; }

int RecordingWriter::append_frame(const std::vector<Image16u>& images, const FrameMetadata& metadata,
                                  const Image32f* depth_m, const BeforeListing& before_listing) {
  return append_any(images, metadata, depth_m, before_listing);
}

int RecordingWriter::append_frame(const std::vector<Image8u>& images, const FrameMetadata& metadata,
                                  const Image32f* depth_m, const BeforeListing& before_listing) {
  return append_any(images, metadata, depth_m, before_listing);
}

template <typename T>
int RecordingWriter::append_any(const std::vector<Image<T>>& images, const FrameMetadata& metadata,
                                const Image32f* depth_m, const BeforeListing& before_listing) {
  if (closed_) throw_error(ErrorCode::kInvalidArgument, "recording {}: append_frame after close()", folder_);
  const RecordingCamera& camera = info_.camera;
  const std::size_t expected = static_cast<std::size_t>(info_.images_per_frame);
  if (metadata.complete ? images.size() != expected : images.size() > expected) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: {} frame with {} images; images_per_frame is {}", folder_,
                metadata.complete ? "complete" : "incomplete", images.size(), expected);
  }
  if (metadata.turntable_angle_deg && !std::isfinite(*metadata.turntable_angle_deg)) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: turntable angle is not finite", folder_);
  }
  if (metadata.capture) check_capture_counters(folder_, *metadata.capture);
  if (expected == 0 && depth_m == nullptr) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: a depth-only recording's frames need a depth map", folder_);
  }
  if (sizeof(T) == 1 && camera.bit_depth > 8) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: 8-bit images for a {}-bit camera", folder_,
                camera.bit_depth);
  }
  // Values must fit the camera's bit depth: an 8-bit recording stores 8-bit PNGs, and a
  // reader relies on 0..2^bit_depth-1 for any depth.
  const unsigned max_value = (1u << camera.bit_depth) - 1u;
  for (std::size_t k = 0; k < images.size(); ++k) {
    const Image<T>& image = images[k];
    if (image.width() != camera.width || image.height() != camera.height) {
      throw_error(ErrorCode::kInvalidArgument, "recording {}: image {} is {}x{}, the camera is {}x{}", folder_, k,
                  image.width(), image.height(), camera.width, camera.height);
    }
    if (max_value < std::numeric_limits<T>::max()) {
      const T* pixels = image.data();
      for (std::size_t i = 0; i < image.pixel_count(); ++i) {
        if (pixels[i] > max_value) {
          throw_error(ErrorCode::kInvalidArgument, "recording {}: image {} has value {} at ({}, {}), above the {}-bit range",
                      folder_, k, pixels[i], i % static_cast<std::size_t>(camera.width),
                      i / static_cast<std::size_t>(camera.width), camera.bit_depth);
        }
      }
    }
  }
  if (depth_m != nullptr && (depth_m->width() != camera.width || depth_m->height() != camera.height)) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: depth map is {}x{}, the camera is {}x{}", folder_,
                depth_m->width(), depth_m->height(), camera.width, camera.height);
  }

  FrameInfo frame;
  frame.index = static_cast<int>(frames_.size());
  frame.timestamp_ns = metadata.timestamp_ns;
  frame.turntable_angle_deg = metadata.turntable_angle_deg;
  frame.complete = metadata.complete;
  frame.note = metadata.note;
  frame.capture = metadata.capture;
  const std::string frame_relative = frame_folder_relative(frame.index);
  const std::string frame_folder = folder_ + "/" + frame_relative;
  create_directories(frame_folder);

  PngWriteOptions png_options;
  png_options.compression_level = options_.png_compression_level;
  for (std::size_t k = 0; k < images.size(); ++k) {
    frame.image_files.push_back(fmt::format("{}/pattern_{:03d}.png", frame_relative, k));
  }
  if (depth_m != nullptr) frame.depth_file = frame_relative + "/depth.png";
  std::size_t depth_out_of_range = 0;
  const std::string& root = folder_;
  const RecordingInfo& info = info_;
  const bool sync = options_.sync;
  // Job k < images.size() writes image k; the last job (when present) the depth map.
  const auto write_job = [&](std::size_t k) {
    if (k < images.size()) {
      const Image<T>& image = images[k];
      std::vector<std::uint8_t> bytes;
      if constexpr (sizeof(T) == 2) {
        if (info.camera.bit_depth <= 8) {
          Image8u narrow(image.width(), image.height());
          const T* in = image.data();
          std::uint8_t* out = narrow.data();
          for (std::size_t i = 0; i < narrow.pixel_count(); ++i) out[i] = static_cast<std::uint8_t>(in[i]);
          bytes = encode_png(narrow.view(), png_options);
        } else {
          bytes = encode_png(image.view(), png_options);
        }
      } else {
        bytes = encode_png(image.view(), png_options);
      }
      write_file_synced(root + "/" + frame.image_files[k], bytes, sync);
    } else {
      const Image16u steps = depth_to_steps(*depth_m, info.depth_unit_m, info.depth_offset_m, &depth_out_of_range);
      write_file_synced(root + "/" + frame.depth_file, encode_png(steps.view(), png_options), sync);
    }
  };
  run_parallel(images.size() + (depth_m != nullptr ? 1 : 0), options_.encode_threads, write_job);
  if (depth_out_of_range > 0) {
    logger().warn("recording {}: frame {}: {} depth pixels outside the storable range {} .. {} m stored as invalid",
                  folder_, frame.index, depth_out_of_range, info_.depth_offset_m + info_.depth_unit_m,
                  info_.depth_offset_m + 65535.0 * info_.depth_unit_m);
  }
  if (options_.sync) {
    sync_directory(frame_folder);
    sync_directory(folder_ + "/" + kFramesName);
  }
  if (before_listing) before_listing(frame.index);
  // Only now does the frame become part of the recording.
  frames_.push_back(std::move(frame));
  try {
    write_manifest();
  } catch (...) {
    frames_.pop_back();
    throw;
  }
  return frames_.back().index;
}

void RecordingWriter::write_manifest() const {
  Json manifest;
  manifest["format"] = kFormatName;
  manifest["format_version"] = info_.exposures.empty() ? 1 : 2;  // 2: what older readers cannot decode
  manifest["created_utc"] = info_.created_utc;
  manifest["device"] = {{"uri", info_.device.uri}, {"model", info_.device.model}, {"serial", info_.device.serial}};
  manifest["camera"] = {
      {"width", info_.camera.width}, {"height", info_.camera.height}, {"bit_depth", info_.camera.bit_depth}};
  manifest["pattern_set"] = Json::parse(info_.pattern_set_json);
  manifest["images_per_frame"] = info_.images_per_frame;
  if (!info_.exposures.empty()) manifest["exposures"] = info_.exposures;
  manifest["calibration"] = has_calibration_ ? Json(kCalibrationName) : Json(nullptr);
  if (info_.has_groundtruth) manifest["groundtruth"] = kGroundtruthName;
  manifest["depth_encoding"] = {
      {"format", kDepthFormat}, {"unit_m", info_.depth_unit_m}, {"offset_m", info_.depth_offset_m}};
  Json frames = Json::array();
  for (const FrameInfo& frame : frames_) frames.push_back(frame_to_json(frame));
  manifest["frames"] = std::move(frames);
  write_file_atomic(folder_ + "/" + kManifestName, manifest.dump(1) + "\n");
}

// ---------------------------------------------------------------------------------------
// Reader

RecordingReader RecordingReader::open(const std::string& folder) {
  RecordingReader reader;
  reader.folder_ = absolute_folder(folder);
  std::error_code error;
  if (!fs::is_directory(reader.folder_, error)) {
    throw_error(ErrorCode::kNotFound, "recording {}: no such folder", reader.folder_);
  }
  const std::string manifest_path = reader.folder_ + "/" + kManifestName;
  // kNotFound naming the file; a FIFO or device in its place is refused without blocking.
  RecordingManifest manifest = parse_recording_manifest(read_file_text(manifest_path), manifest_path);
  reader.info_ = std::move(manifest.info);
  reader.frames_ = std::move(manifest.frames);
  reader.groundtruth_relative_ = std::move(manifest.groundtruth_relative);
  const std::string& calibration_relative = manifest.calibration_relative;
  if (!calibration_relative.empty()) {
    const std::string calibration_path = reader.file_path(calibration_relative);
    if (!fs::exists(calibration_path, error)) {
      throw_error(ErrorCode::kNotFound, "recording {}: calibration file {} is missing", reader.folder_,
                  calibration_path);
    }
    reader.calibration_ = read_calibration(calibration_path);
  }
  if (reader.info_.has_groundtruth && !fs::is_directory(reader.groundtruth_folder(), error)) {
    throw_error(ErrorCode::kNotFound, "recording {}: groundtruth folder {} is missing", reader.folder_,
                reader.groundtruth_folder());
  }
  return reader;
}

const ScannerCalibration& RecordingReader::calibration() const {
  if (!calibration_) throw_error(ErrorCode::kNotFound, "recording {}: recorded without calibration", folder_);
  return *calibration_;
}

const FrameInfo& RecordingReader::frame(std::size_t position) const {
  if (position >= frames_.size()) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: frame {} does not exist ({} frames)", folder_, position,
                frames_.size());
  }
  return frames_[position];
}

std::string RecordingReader::file_path(const std::string& relative) const { return folder_ + "/" + relative; }

std::string RecordingReader::groundtruth_folder() const {
  return groundtruth_relative_.empty() ? std::string() : file_path(groundtruth_relative_);
}

namespace {

template <typename T>
void check_size(const Image<T>& image, const RecordingCamera& camera, const std::string& path, const char* what) {
  if (image.width() != camera.width || image.height() != camera.height) {
    throw_error(ErrorCode::kFormat, "{}: {} is {}x{}, the recording's camera is {}x{}", path, what, image.width(),
                image.height(), camera.width, camera.height);
  }
}

}  // namespace

Image16u RecordingReader::load_image(std::size_t position, std::size_t image, MemoryType memory) const {
  return load_image_in(position, image, nullptr, memory);
}

Image16u RecordingReader::load_image(std::size_t position, std::size_t image, const ImageRegion& region,
                                     MemoryType memory) const {
  return load_image_in(position, image, &region, memory);
}

Image16u RecordingReader::load_image_in(std::size_t position, std::size_t image, const ImageRegion* region,
                                        MemoryType memory) const {
  const FrameInfo& info = frame(position);
  if (image >= info.image_files.size()) {
    throw_error(ErrorCode::kInvalidArgument, "recording {}: frame {} has {} images, no image {}", folder_, position,
                info.image_files.size(), image);
  }
  const std::string path = file_path(info.image_files[image]);
  Image16u pixels;
  if (region == nullptr) {
    pixels = read_png_u16(path, memory);
    check_size(pixels, info_.camera, path, "image");
  } else {
    const PngHeader header = read_png_header(path);
    if (header.width != info_.camera.width || header.height != info_.camera.height) {
      throw_error(ErrorCode::kFormat, "{}: image is {}x{}, the recording's camera is {}x{}", path, header.width,
                  header.height, info_.camera.width, info_.camera.height);
    }
    pixels = read_png_u16(path, *region, memory);
  }
  // Values beyond the camera's bit depth (an image scaled to 16 bits, another camera's) would
  // decode to wrong stripes, not to no data: the image is refused instead.
  if (info_.camera.bit_depth > 0 && info_.camera.bit_depth < 16) {
    const std::uint16_t largest = *std::max_element(pixels.data(), pixels.data() + pixels.pixel_count());
    const int limit = (1 << info_.camera.bit_depth) - 1;
    if (largest > limit) {
      throw_error(ErrorCode::kFormat, "{}: pixel values up to {}, beyond the recording's {}-bit camera (at most {})",
                  path, largest, info_.camera.bit_depth, limit);
    }
  }
  return pixels;
}

std::vector<Image16u> RecordingReader::load_images(std::size_t position, MemoryType memory) const {
  const FrameInfo& info = frame(position);
  // A 12 MP stack is ~1 GB: admitted before it is allocated, as the volume is (Linux
  // overcommits, so a stack that does not fit would otherwise end in the OOM killer).
  const std::uint64_t stack_bytes = static_cast<std::uint64_t>(info.image_files.size()) *
                                    static_cast<std::uint64_t>(info_.camera.width) *
                                    static_cast<std::uint64_t>(info_.camera.height) * sizeof(std::uint16_t);
  admit_host_allocation(stack_bytes,
                        fmt::format("frame {}'s pattern stack ({} images of {}x{})", info.index,
                                    info.image_files.size(), info_.camera.width, info_.camera.height),
                        "free memory for it (other programs, a smaller volume: --voxel-um / --max-voxels)");
  // Decoding is CPU-bound (~0.1 s per 24 MB image): decode the frame's images side by side.
  std::vector<Image16u> images(info.image_files.size());
  run_parallel(images.size(), 0, [&](std::size_t k) { images[k] = load_image(position, k, memory); });
  return images;
}

std::vector<Image16u> RecordingReader::load_images(std::size_t position, const ImageRegion& region,
                                                   MemoryType memory) const {
  std::vector<Image16u> images(frame(position).image_files.size());
  run_parallel(images.size(), 0, [&](std::size_t k) { images[k] = load_image(position, k, region, memory); });
  return images;
}

std::optional<Image32f> RecordingReader::load_depth_m(std::size_t position) const {
  const FrameInfo& info = frame(position);
  if (!info.has_depth()) return std::nullopt;
  const std::string path = file_path(info.depth_file);
  AnyImage stored = read_png(path);
  const auto* steps = std::get_if<Image16u>(&stored);
  if (steps == nullptr) throw_error(ErrorCode::kFormat, "{}: depth map must be a 16-bit PNG, it is 8-bit", path);
  check_size(*steps, info_.camera, path, "depth map");
  return steps_to_depth(*steps, info_.depth_unit_m, info_.depth_offset_m);
}

void RecordingReader::verify(bool decode_pixels) const {
  for (std::size_t i = 0; i < frames_.size(); ++i) {
    const FrameInfo& info = frames_[i];
    std::vector<std::string> files = info.image_files;
    if (info.has_depth()) files.push_back(info.depth_file);
    for (const std::string& relative : files) {
      const std::string path = file_path(relative);
      const PngHeader header = read_png_header(path);
      if (header.width != info_.camera.width || header.height != info_.camera.height) {
        throw_error(ErrorCode::kFormat, "{}: image is {}x{}, the recording's camera is {}x{}", path, header.width,
                    header.height, info_.camera.width, info_.camera.height);
      }
    }
    if (decode_pixels) {
      (void)load_images(i);
      (void)load_depth_m(i);
    }
  }
}

std::string head_camera_folder(const std::string& head, std::size_t camera) {
  return (std::filesystem::path(head) / fmt::format("camera{}", camera)).string();
}

Image32f recorded_depth_m(const Image32f& depth_m, const RecordingInfo& info) {
  std::size_t out_of_range = 0;
  return steps_to_depth(depth_to_steps(depth_m, info.depth_unit_m, info.depth_offset_m, &out_of_range),
                        info.depth_unit_m, info.depth_offset_m);
}

}  // namespace sls
