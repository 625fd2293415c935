// Recordings (DESIGN.md section 5): one scan session on disk, replayable with no hardware.
//
//   <folder>/manifest.json         what was recorded (below); rewritten atomically per frame
//   <folder>/calibration.yml       sls::write_calibration format (absent when recorded
//                                  uncalibrated, e.g. a calibration capture: manifest says null)
//   <folder>/frames/NNNNNN/pattern_KKK.png   the camera images of frame N, pattern K
//   <folder>/frames/NNNNNN/depth.png         optional depth map (16-bit PNG, see below)
//   <folder>/groundtruth/          optional; content defined by the simulator
//
// manifest.json:
//   {"format": "slscan-recording", "format_version": 1, "created_utc": "2024-01-31T12:00:00Z",
//    "device": {"uri", "model", "serial"}, "camera": {"width", "height", "bit_depth"},
//    "pattern_set": {...caller's JSON object...}, "images_per_frame": N,
//    (images_per_frame 0: a depth-only recording, every frame has a depth map),
//    "exposures": [1.0, 0.25] (optional, format_version 2: an HDR capture; each frame holds
//      the whole stack at each exposure in turn, images_per_frame = patterns x exposures),
//    "calibration": "calibration.yml" | null, "groundtruth": "groundtruth" (optional),
//    "depth_encoding": {"format": "png16", "unit_m": 1e-6, "offset_m": 0.0},
//    "frames": [{"index", "timestamp_ns", "turntable_angle_deg": number|null,
//                "images": ["frames/000000/pattern_000.png", ...],
//                "depth": "frames/000000/depth.png" (optional),
//                "status": "complete"|"incomplete", "note": "..." (optional),
//                "capture": {...} (optional, FrameCaptureCounters)}]}
//   "capture" (frames captured through the capture sequencer): {"attempts", "incomplete_images",
//   "lost_images", "stale_images"} and, when the cameras' transport counts them, also
//   {"resent_packets", "missing_packets", "queue_depth"}. Absent in recordings made otherwise
//   or before it was kept: readers treat it as unknown, not as zero.
//
// Pixel values: stored as captured, unscaled. A camera of bit_depth <= 8 is stored as 8-bit
// PNG, deeper ones (10/12/14/16) as 16-bit PNG holding values 0..2^bit_depth-1.
//
// Depth maps: metres (float) in memory, 0 = invalid. On disk a 16-bit PNG of integer steps:
// depth = offset_m + value * unit_m, value 0 = invalid. With the defaults (1 µm, offset 0)
// the storable range is 1 µm .. 65.535 mm, exact to 1 µm (rounded to nearest); set
// RecordingInfo::depth_offset_m (and/or depth_unit_m) for a scanner whose stand-off is
// longer. Depths outside the storable range are stored as invalid (0), not clamped: a
// clamped depth would be a fabricated surface.
//
// Crash safety: each frame's PNGs are written and fsync'ed before manifest.json is replaced
// (write to a temporary, fsync, rename), so an interrupted recording always reads back as
// the frames completed before the interruption; stray files of an unfinished frame are
// not listed and are ignored.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "sdk/core/calibration.h"
#include "sdk/core/image.h"
#include "sdk/core/image_io.h"

namespace sls {

struct RecordingDevice {
  std::string uri;
  std::string model;
  std::string serial;
};

struct RecordingCamera {
  int width = 0;
  int height = 0;
  int bit_depth = 8;  // as captured, 1..16 (8, 10, 12, 14, 16 in practice)
};

struct RecordingInfo {
  // The newest format this SDK reads and writes. A recording is written as version 1 unless
  // it needs 2 (exposures), so older readers keep reading what they can decode.
  static constexpr int kFormatVersion = 2;

  RecordingDevice device;
  RecordingCamera camera;
  // The pattern set as a JSON object (name, image count, metadata). Opaque to the core; the
  // writer checks that it parses as an object and stores it normalised (compact, key order kept).
  std::string pattern_set_json = "{}";
  int images_per_frame = 0;
  bool has_groundtruth = false;
  double depth_unit_m = 1e-6;   // size of one depth step on disk
  double depth_offset_m = 0.0;  // depth of step 0 (step 0 itself means invalid)
  std::string created_utc;      // ISO 8601, set by the writer; read back by the reader
  // HDR (sdk/decode/hdr_fusion.h): the frame's stack was captured at these exposure times
  // relative to the camera's configured one, 1..4 of them; images_per_frame counts all the
  // images (patterns x exposures, exposure-major). Empty: one exposure, as before.
  std::vector<double> exposures;
};

// A frame's figures from the cameras' transport (GigE Vision streams), summed over the cameras:
// the packets the stream counted since the previous frame ended (or the acquisition began).
struct FrameTransportCounters {
  std::uint64_t resent_packets = 0;   // sent again by a camera on request
  std::uint64_t missing_packets = 0;  // missing from the images the transport could not complete
  // The most images one camera's output queue held behind an image the capture took for this
  // frame: how far behind the capture was (0: it kept up).
  std::uint64_t queue_depth = 0;
};

// What capturing a frame took (the capture sequencer's counts for this frame alone), kept in
// the recording so that a scan of it can report them.
struct FrameCaptureCounters {
  int attempts = 1;           // 1 + re-captures of the stack
  int incomplete_images = 0;  // the transport could not complete them, over every attempt and camera
  int lost_images = 0;        // never arrived: frame-id gaps and timeouts
  int stale_images = 0;       // arrived late for an earlier trigger and were dropped
  std::optional<FrameTransportCounters> transport;  // none when no camera's transport counts
};

bool operator==(const FrameTransportCounters& a, const FrameTransportCounters& b);
bool operator==(const FrameCaptureCounters& a, const FrameCaptureCounters& b);
inline bool operator!=(const FrameCaptureCounters& a, const FrameCaptureCounters& b) { return !(a == b); }

struct FrameMetadata {
  std::int64_t timestamp_ns = 0;
  std::optional<double> turntable_angle_deg;
  // false: the capture was cut short (e.g. a timeout); the frame may then hold fewer images
  // than images_per_frame, always the first ones of the pattern sequence.
  bool complete = true;
  std::string note;
  // How the capture went (the capture sequencer's); none for frames made otherwise.
  std::optional<FrameCaptureCounters> capture;
};

struct FrameInfo {
  int index = 0;
  std::int64_t timestamp_ns = 0;
  std::optional<double> turntable_angle_deg;
  bool complete = true;
  std::string note;
  std::optional<FrameCaptureCounters> capture;  // absent when the manifest has none
  std::vector<std::string> image_files;  // relative to the recording folder
  std::string depth_file;                // relative; empty when the frame has no depth map
  bool has_depth() const { return !depth_file.empty(); }
};

struct RecordingWriterOptions {
  int png_compression_level = 1;  // zlib 0..9; live capture needs speed
  bool sync = true;               // fsync every file (turn off only for tests and scratch data)
  int encode_threads = 0;         // threads encoding one frame's PNGs; 0 = one per hardware thread
};

// A head of several cameras on disk (issue 17): one recording (or folder of captures) per
// camera, `head`/camera0, `head`/camera1, ... — what `sls sim --calibration --cameras N` and a
// head's calibration capture write, and `sls calibrate --input head` reads.
std::string head_camera_folder(const std::string& head, std::size_t camera);

// A depth map as a recording of `info` stores it and reads it back (quantised to depth_unit_m
// from depth_offset_m; out of range: 0): what a scan fused while capturing takes, so that it
// equals a replay of the recording.
Image32f recorded_depth_m(const Image32f& depth_m, const RecordingInfo& info);

// Writes a recording frame by frame. Not thread-safe: one thread appends (each append
// encodes its images on several threads itself). Move-only: one writer per folder.
class RecordingWriter {
 public:
  RecordingWriter(RecordingWriter&&) noexcept = default;
  RecordingWriter& operator=(RecordingWriter&&) noexcept = default;
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // Creates `folder` (and its parents) and writes calibration.yml (when given) and an empty
  // manifest. Throws kInvalidArgument for an existing non-empty folder or a bad `info`
  // (sizes, bit depth, images_per_frame, pattern_set_json that is not a JSON object, a
  // calibration whose camera size differs from the recording's), kIo when writing fails.
  static RecordingWriter create(const std::string& folder, const RecordingInfo& info,
                                const std::optional<ScannerCalibration>& calibration,
                                const RecordingWriterOptions& options = {});

  // Continues a recording this writer made that was cut off (a signal, kill -9, a device
  // error): its manifest is read and checked as RecordingReader::open does, and frames are
  // appended after the listed ones (files an unlisted frame left behind are overwritten).
  // Throws RecordingReader::open's errors (kNotFound, kFormat, kVersionMismatch), and
  // kInvalidArgument for a recording it cannot continue: frame indices other than 0..n-1, a
  // calibration or ground truth under another name than the writer gives them.
  static RecordingWriter append_to(const std::string& folder, const RecordingWriterOptions& options = {});

  // Appends one frame: writes its images (and depth map), then the manifest listing it.
  // Images must match the camera size; 16-bit images for bit_depth > 8, 8-bit images (or
  // 16-bit ones holding values <= 255) for bit_depth <= 8; values must fit bit_depth.
  // A complete frame has exactly images_per_frame images, an incomplete one at most that.
  // `depth_m` (metres, 0 or non-finite = invalid) must match the camera size. Capture
  // counters, when given, need attempts >= 1, counts >= 0 and packet counts below 2^63.
  // Returns the frame's index. On failure (kInvalidArgument, kIo) nothing is listed and
  // the recording stays valid; the next append reuses the index.
  // `before_listing`, when given, is called with the frame's index once its files are on
  // disk and before the manifest lists it: where a caller writes files of its own that
  // belong to the frame (the simulator's ground truth), so a listed frame always has them.
  // An exception from it leaves the frame unlisted and propagates.
  using BeforeListing = std::function<void(int index)>;
  int append_frame(const std::vector<Image16u>& images, const FrameMetadata& metadata,
                   const Image32f* depth_m = nullptr, const BeforeListing& before_listing = {});
  int append_frame(const std::vector<Image8u>& images, const FrameMetadata& metadata,
                   const Image32f* depth_m = nullptr, const BeforeListing& before_listing = {});

  const std::string& folder() const { return folder_; }
  const RecordingInfo& info() const { return info_; }
  std::size_t frame_count() const { return frames_.size(); }
  const FrameInfo& frame(std::size_t position) const;
  // Absolute path of groundtruth/ (created by create()); empty when !info().has_groundtruth.
  std::string groundtruth_folder() const;

  // Ends the recording; appending afterwards is an error. The manifest is already complete
  // after every append, so destroying a writer without close() loses nothing.
  void close();
  bool is_closed() const { return closed_; }

 private:
  RecordingWriter() = default;
  template <typename T>
  int append_any(const std::vector<Image<T>>& images, const FrameMetadata& metadata, const Image32f* depth_m,
                 const BeforeListing& before_listing);
  void write_manifest() const;

  std::string folder_;
  RecordingInfo info_;
  bool has_calibration_ = false;
  RecordingWriterOptions options_;
  std::vector<FrameInfo> frames_;
  bool closed_ = false;
};

// Reads a recording. open() validates the manifest and reads the calibration; images are
// loaded on demand and checked then. All methods are const and keep no state, so several
// threads may load frames from one reader at once. Errors are sls::Error naming the file: kNotFound
// (missing folder, manifest, calibration or image), kFormat (corrupt JSON with its byte
// position, missing or mistyped keys, paths leaving the folder, undecodable or mis-sized
// images), kVersionMismatch (format_version newer than this SDK writes).
class RecordingReader {
 public:
  static RecordingReader open(const std::string& folder);

  const std::string& folder() const { return folder_; }
  const RecordingInfo& info() const { return info_; }
  bool has_calibration() const { return calibration_.has_value(); }
  // Throws kNotFound when the recording was made without calibration.
  const ScannerCalibration& calibration() const;

  std::size_t frame_count() const { return frames_.size(); }
  // By position in the manifest (0 .. frame_count()-1); kInvalidArgument when out of range.
  const FrameInfo& frame(std::size_t position) const;

  // Absolute path of a file named relative to the folder in a FrameInfo.
  std::string file_path(const std::string& relative) const;

  // One image as captured, as 16-bit (8-bit PNGs widened by value, no scaling), checked to
  // exist, decode and have the camera's size.
  // `memory`: where the pixels go (MemoryType::kPinned for a scan fused on a GPU, whose decoder
  // then uploads them without staging; page-locked where a GPU can lock it, else pageable).
  Image16u load_image(std::size_t position, std::size_t image, MemoryType memory = MemoryType::kHost) const;
  // All images of a frame, in pattern order (decoded on several threads).
  std::vector<Image16u> load_images(std::size_t position, MemoryType memory = MemoryType::kHost) const;
  // As those two, only the pixels of `region` (inside the camera's image, else
  // kInvalidArgument): what a calibration reads around its board.
  Image16u load_image(std::size_t position, std::size_t image, const ImageRegion& region,
                      MemoryType memory = MemoryType::kHost) const;
  std::vector<Image16u> load_images(std::size_t position, const ImageRegion& region,
                                    MemoryType memory = MemoryType::kHost) const;
  // The frame's depth map in metres (0 = invalid), or nullopt when it has none.
  std::optional<Image32f> load_depth_m(std::size_t position) const;

  // Checks that every listed file exists with a valid PNG header of the camera's size
  // (decode_pixels: also decodes every image, slow). Throws on the first problem.
  void verify(bool decode_pixels = false) const;

  // Absolute path of groundtruth/, empty when the recording has none.
  std::string groundtruth_folder() const;

 private:
  RecordingReader() = default;
  Image16u load_image_in(std::size_t position, std::size_t image, const ImageRegion* region, MemoryType memory) const;

  std::string folder_;
  RecordingInfo info_;
  std::optional<ScannerCalibration> calibration_;
  std::vector<FrameInfo> frames_;
  std::string groundtruth_relative_;
};

}  // namespace sls
