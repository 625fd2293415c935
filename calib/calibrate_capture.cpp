#include "calib/calibrate_capture.h"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>
#include <future>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/recording.h"
#include "sdk/core/run_parallel.h"
#include "sdk/core/stopwatch.h"

namespace sls::calib {
namespace {

namespace fs = std::filesystem;

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

// The board of a simulated capture (groundtruth/board.json), for a board not given.
BoardSpec read_board_json(const std::string& path) {
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(read_file_text(path));
    BoardSpec board;
    board.inner_cols = json.at("inner_corners").at(0).get<int>();
    board.inner_rows = json.at("inner_corners").at(1).get<int>();
    board.square_m = json.at("square_m").get<double>();
    if (json.contains("kind") && json.at("kind").is_string() && json.at("kind").get_ref<const std::string&>() == "charuco") {  // sls sim --calibration --board charuco
      board.kind = BoardKind::kCharuco;
      board.marker_m = json.at("marker_m").get<double>();
      board.dictionary = json.at("dictionary").get<std::string>();
    }
    return board;
  } catch (const nlohmann::json::exception& error) {
    throw_error(ErrorCode::kFormat, "{}: not a board description: {}", path, error.what());
  }
}

struct Source {
  std::string kind;
  PatternSet patterns;
  DecodeOptions decode;
  int bit_depth = 0;
  int width = 0, height = 0;
  std::vector<std::string> names;
  std::vector<std::optional<double>> angles;
  std::vector<std::string> skipped;  // per view: non-empty when it cannot be used at all
  // A view's image (white and black, where the board is looked for), and all of its images
  // cropped to the board's region (each checked to have the capture's size).
  std::function<Image16u(std::size_t view, std::size_t image)> load_image;
  std::function<std::vector<Image16u>(std::size_t view, const ImageRegion& region)> load_region;
  std::string groundtruth;           // folder, empty when none
};

Source open_recording(const std::string& folder, const std::string& pattern_name) {
  auto reader = std::make_shared<RecordingReader>(RecordingReader::open(folder));
  Source source;
  source.kind = "recording";
  const RecordingInfo& info = reader->info();
  if (info.images_per_frame == 0) {
    throw_error(ErrorCode::kInvalidArgument, "{}: a depth-only recording has no pattern images to calibrate from",
                folder);
  }
  source.patterns = pattern_name.empty() ? pattern_set_from_json(info.pattern_set_json) : pattern_set_from_name(pattern_name);
  source.bit_depth = info.camera.bit_depth;
  source.width = info.camera.width;
  source.height = info.camera.height;
  source.decode.bit_depth = info.camera.bit_depth;  // the recording's camera, as a scan decodes it
  for (std::size_t i = 0; i < reader->frame_count(); ++i) {
    const FrameInfo& frame = reader->frame(i);
    source.names.push_back(fmt::format("frame {}", frame.index));
    source.angles.push_back(frame.turntable_angle_deg);
    source.skipped.push_back(frame.complete ? "" : "incomplete frame (capture cut short)");
  }
  source.load_image = [reader](std::size_t i, std::size_t k) { return reader->load_image(i, k); };
  source.load_region = [reader](std::size_t i, const ImageRegion& region) { return reader->load_images(i, region); };
  source.groundtruth = reader->groundtruth_folder();
  return source;
}

std::vector<std::string> sorted_entries(const std::string& folder, bool directories) {
  std::vector<std::string> out;
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(folder, error)) {
    if (directories ? entry.is_directory() : (entry.is_regular_file() && entry.path().extension() == ".png")) {
      out.push_back(entry.path().string());
    }
  }
  if (error) throw_error(ErrorCode::kIo, "{}: cannot list: {}", folder, error.message());
  std::sort(out.begin(), out.end());
  return out;
}

Source open_folder(const std::string& folder, const std::string& pattern_name) {
  if (pattern_name.empty()) {
    throw_error(ErrorCode::kInvalidArgument,
                "{} is a folder of captures: name its pattern set (e.g. --patterns opencv-graycode:1024x768)", folder);
  }
  Source source;
  source.kind = "folder";
  source.patterns = pattern_set_from_name(pattern_name);
  const std::vector<std::string> poses = sorted_entries(folder, true);
  if (poses.empty()) {
    throw_error(ErrorCode::kNotFound, "{}: no subfolders (one per board pose) and no manifest.json", folder);
  }
  std::vector<std::vector<std::string>> files;
  for (const std::string& pose : poses) {
    files.push_back(sorted_entries(pose, false));
    if (files.back().size() != source.patterns.size()) {
      throw_error(ErrorCode::kInvalidArgument, "{}: {} PNG images, the pattern set '{}' has {}", pose,
                  files.back().size(), source.patterns.name, source.patterns.size());
    }
    source.names.push_back(fs::path(pose).filename().string());
    source.angles.emplace_back();
    source.skipped.emplace_back();
  }
  const PngHeader header = read_png_header(files.front().front());
  source.bit_depth = header.bit_depth;
  source.width = header.width;
  source.height = header.height;
  source.decode = decode_options_for_unknown_camera(header.bit_depth);
  const auto check_size = [header](const std::string& path, int width, int height) {
    if (width != header.width || height != header.height) {
      throw_error(ErrorCode::kFormat, "{}: {}x{} image, the capture's first is {}x{}", path, width, height,
                  header.width, header.height);
    }
  };
  source.load_image = [files, check_size](std::size_t i, std::size_t k) {
    Image16u image = read_png_u16(files[i][k]);
    check_size(files[i][k], image.width(), image.height());
    return image;
  };
  source.load_region = [files, check_size](std::size_t i, const ImageRegion& region) {
    std::vector<Image16u> stack(files[i].size());
    run_parallel(stack.size(), 0, [&](std::size_t k) {
      const PngHeader image = read_png_header(files[i][k]);
      check_size(files[i][k], image.width, image.height);
      stack[k] = read_png_u16(files[i][k], region);
    });
    return stack;
  };
  return source;
}

}  // namespace

CalibrateCaptureResult calibrate_capture(const CalibrateCaptureOptions& options, const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  if (!fs::is_directory(options.input)) {
    throw_error(ErrorCode::kNotFound, "{}: not a recording or a folder of captures", options.input);
  }
  Source source = fs::exists(fs::path(options.input) / "manifest.json") ? open_recording(options.input, options.patterns)
                                                                          : open_folder(options.input, options.patterns);
  CalibrateCaptureResult result;
  result.input_kind = source.kind;
  result.pattern_set_name = source.patterns.name;
  result.camera_bit_depth = source.bit_depth;
  result.board = options.board;
  const std::string board_json = source.groundtruth.empty() ? "" : source.groundtruth + "/board.json";
  if (result.board.square_m <= 0.0 && result.board.inner_cols <= 0 && !result.board.is_charuco() &&
      !board_json.empty() && fs::exists(board_json)) {
    result.board = read_board_json(board_json);
  }
  if (result.board.inner_cols <= 0 || result.board.inner_rows <= 0 || result.board.square_m <= 0.0) {
    throw_error(ErrorCode::kInvalidArgument,
                "the board is not described: give its inner corners and square size (--board COLSxROWS --square M)");
  }
  result.board.validate();

  ObservationOptions observation;
  observation.board = result.board;
  observation.decode = source.decode;
  observation.min_projector_corner_fraction = options.min_projector_corner_fraction;
  observation.device = options.device;
  const std::size_t count = source.names.size();
  // A view that cannot be read (a missing, corrupt or mis-sized image) is rejected with the
  // reason, not fatal: the other views still calibrate. The next view is read, and its board
  // found, while this one is decoded: its white and black images whole, then, once the board
  // is found, only the board's region of each image (a quarter of a 4000 x 3000 image,
  // typically: a PNG's rows below it are not even unfiltered).
  struct LoadedView {
    BoardSighting sighting;
    std::vector<Image16u> region_stack;
    std::string reason;
    double seconds = 0.0;  // reading the images, the board's detection left out
  };
  const std::size_t white_index = white_image_index(source.patterns);
  const std::size_t black_index = black_image_index(source.patterns);
  const auto load_view = [&source, &observation, white_index, black_index](std::size_t i) {
    LoadedView loaded;
    loaded.reason = source.skipped[i];
    if (!loaded.reason.empty()) return loaded;
    const auto load_start = std::chrono::steady_clock::now();
    try {
      std::vector<Image16u> references(2);
      run_parallel(references.size(), 0,
                   [&](std::size_t k) { references[k] = source.load_image(i, k == 0 ? white_index : black_index); });
      loaded.sighting = sight_board(references[0], references[1], observation);
      if (loaded.sighting.board.found) loaded.region_stack = source.load_region(i, loaded.sighting.region);
    } catch (const Error& error) {
      if (error.code() == ErrorCode::kOutOfMemory) throw;
      loaded.reason = error.what();
    }
    loaded.seconds = 1e-3 * ms_since(load_start) - loaded.sighting.detect_s;
    return loaded;
  };
  std::future<LoadedView> next;
  if (count > 0) next = std::async(std::launch::async, load_view, std::size_t{0});
  for (std::size_t i = 0; i < count; ++i) {
    LoadedView loaded = next.get();
    if (i + 1 < count) next = std::async(std::launch::async, load_view, i + 1);
    report_progress(progress, {"calibrate", i, count, source.names[i]});
    result.load_s += loaded.seconds;
    if (!loaded.reason.empty()) {
      ViewObservation rejected;
      rejected.name = source.names[i];
      rejected.turntable_angle_deg = source.angles[i];
      rejected.rejected_reason = loaded.reason;
      result.views.push_back(std::move(rejected));
      continue;
    }
    result.views.push_back(observe_sighted_view(source.names[i], source.angles[i], loaded.sighting,
                                                loaded.region_stack, source.patterns, observation));
    result.detect_s += result.views.back().detect_s;
    result.decode_s += result.views.back().decode_s;
    result.homography_s += result.views.back().homography_s;
  }
  report_progress(progress, {"calibrate", count, count, "solve"});
  const auto solve_start = std::chrono::steady_clock::now();

  ProcamSettings settings;
  settings.board = result.board;
  settings.camera_width = source.width;
  settings.camera_height = source.height;
  settings.projector_width = source.patterns.projector_width;
  settings.projector_height = source.patterns.projector_height;
  settings.estimate_k3 = options.estimate_k3;
  settings.max_obliquity_deg = options.max_obliquity_deg;
  // The solve's steps: the procam's, then the turntable axis (each camera's ~1-3 s at ci sizes).
  constexpr std::size_t kSolveSteps = kProcamSolveSteps + 1;
  const ProgressCallback solve_progress = [&progress](const ProgressUpdate& update) {
    return !progress || progress({update.stage, update.done, kSolveSteps, update.detail});
  };
  result.procam = calibrate_procam(result.views, settings, solve_progress);
  report_progress(progress, {"solve", kProcamSolveSteps, kSolveSteps, "turntable axis"});
  result.axis = fit_turntable_axis(result.views, result.procam.views, result.procam.calibration, result.board);
  report_progress(progress, {"solve", kSolveSteps, kSolveSteps, "solved"});
  result.solve_s = 1e-3 * ms_since(solve_start);
  ScannerCalibration& calibration = result.procam.calibration;
  if (result.axis.fitted) calibration.turntable = result.axis.axis;
  calibration.camera_rms_px = result.procam.camera_rms_px;
  calibration.projector_rms_px = result.procam.projector_rms_px;
  calibration.calibrated_utc = utc_now();
  calibration.description = fmt::format(
      "slscan calibrate: {} of {} board views ({}), pattern set {}, camera {:.3f} px, "
      "projector {:.3f} px, stereo {:.3f} px RMS{}",
      result.procam.views_used, count,
      result.board.is_charuco()
          ? result.board.describe()
          : fmt::format("{}x{} corners, {} m squares", result.board.inner_cols, result.board.inner_rows,
                        result.board.square_m),
      source.patterns.name, result.procam.camera_rms_px, result.procam.projector_rms_px, result.procam.stereo_rms_px,
      result.axis.fitted ? fmt::format(", turntable axis from {} views", result.axis.views) : "");

  const std::string truth_path = source.groundtruth.empty() ? "" : source.groundtruth + "/calibration.yml";
  if (!truth_path.empty() && fs::exists(truth_path)) {
    result.truth = read_calibration(truth_path);
    result.errors = compare_calibrations(calibration, *result.truth);
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace sls::calib
