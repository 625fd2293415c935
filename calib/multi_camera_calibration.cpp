#include "calib/multi_camera_calibration.h"

#include <chrono>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include "calib/opencv_conversions.h"
#include "sdk/core/error.h"
#include "sdk/core/recording.h"

namespace sls::calib {
namespace {

namespace fs = std::filesystem;

// stereoCalibrate's stop: run to convergence (procam_calibration.cpp says why a looser stop
// leaves the narrow field's flat valley early).
const cv::TermCriteria kConvergence(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 500, 1e-15);

bool inlier(const std::vector<std::uint8_t>& mask, std::size_t corner) {
  return corner < mask.size() && mask[corner] != 0;
}

// A view's corner ids (all of the board's, in order, for a view made without them), checked.
std::vector<int> corner_ids(const ViewObservation& view, std::size_t board_corners) {
  std::vector<int> ids = view.corner_ids;
  if (ids.empty()) {
    ids.resize(view.camera_corners.size());
    for (std::size_t c = 0; c < ids.size(); ++c) ids[c] = static_cast<int>(c);
  }
  for (int id : ids) {
    if (id < 0 || static_cast<std::size_t>(id) >= board_corners) {
      throw_error(ErrorCode::kInvalidArgument, "view '{}': corner id {} is not one of the board's {}", view.name, id,
                  board_corners);
    }
  }
  return ids;
}

std::string camera_folder(const std::string& folder, std::size_t camera) { return head_camera_folder(folder, camera); }

// The board poses a camera's capture holds, before anything is read: a recording's frames,
// or a folder's pose subfolders.
std::size_t board_pose_count(const std::string& folder) {
  if (fs::exists(fs::path(folder) / "manifest.json")) return RecordingReader::open(folder).frame_count();
  std::size_t count = 0;
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(folder, error)) count += entry.is_directory() ? 1u : 0u;
  if (error) throw_error(ErrorCode::kIo, "{}: cannot list: {}", folder, error.message());
  return count;
}

}  // namespace

CameraPairSolution calibrate_camera_pair(const std::vector<ViewObservation>& views0, const ProcamCalibration& camera0,
                                         const std::vector<ViewObservation>& views, const ProcamCalibration& camera,
                                         const BoardSpec& board, int min_views) {
  if (views0.size() != views.size() || camera0.views.size() != views0.size() || camera.views.size() != views.size()) {
    throw_error(ErrorCode::kInvalidArgument, "the two cameras have {} and {} board poses (they must see the same ones)",
                views0.size(), views.size());
  }
  // In board squares, as the procam solve: OpenCV's Levenberg–Marquardt is unscaled.
  const double unit = board.square_m;
  const std::vector<Eigen::Vector3d> object = board.object_points();
  std::vector<std::vector<cv::Point3f>> object_points;
  std::vector<std::vector<cv::Point2f>> points0, points;
  CameraPairSolution solution;
  for (std::size_t v = 0; v < views.size(); ++v) {
    const ViewSolution& s0 = camera0.views[v];
    const ViewSolution& s = camera.views[v];
    if (!s0.used || !s.used) continue;
    object_points.emplace_back();
    points0.emplace_back();
    points.emplace_back();
    // The corners both cameras found (by id: a ChArUco view has those it saw), camera 0's order.
    const std::vector<int> ids0 = corner_ids(views0[v], object.size());
    const std::vector<int> ids = corner_ids(views[v], object.size());
    std::vector<int> position(object.size(), -1);  // of each id among camera K's corners
    for (std::size_t c = 0; c < ids.size(); ++c) position[static_cast<std::size_t>(ids[c])] = static_cast<int>(c);
    for (std::size_t c0 = 0; c0 < ids0.size(); ++c0) {
      const int c = position[static_cast<std::size_t>(ids0[c0])];
      if (c < 0 || !inlier(s0.camera_inlier, c0) || !inlier(s.camera_inlier, static_cast<std::size_t>(c))) continue;
      object_points.back().push_back(
          to_cv(std::vector<Eigen::Vector3d>{object[static_cast<std::size_t>(ids0[c0])] / unit}).front());
      points0.back().push_back(to_cv(views0[v].camera_corners[c0]));
      points.back().push_back(to_cv(views[v].camera_corners[static_cast<std::size_t>(c)]));
    }
    // A pose needs at least 4 points to be solved at all; a handful more to count.
    if (object_points.back().size() < 6) {
      object_points.pop_back();
      points0.pop_back();
      points.pop_back();
      continue;
    }
    ++solution.views;
    solution.corners += static_cast<int>(object_points.back().size());
  }
  if (solution.views < min_views) {
    throw_error(ErrorCode::kInvalidArgument,
                "only {} board pose(s) used by both cameras (at least {} are needed for their relative pose)",
                solution.views, min_views);
  }
  const CameraIntrinsics& intrinsics0 = camera0.calibration.camera;
  const CameraIntrinsics& intrinsics = camera.calibration.camera;
  cv::Mat k0 = camera_matrix_of(intrinsics0), d0 = distortion_of(intrinsics0);
  cv::Mat k = camera_matrix_of(intrinsics), d = distortion_of(intrinsics);
  cv::Mat rotation, translation, essential, fundamental;
  solution.rms_px = cv::stereoCalibrate(object_points, points0, points, k0, d0, k, d,
                                        cv::Size(intrinsics0.width, intrinsics0.height), rotation, translation,
                                        essential, fundamental, cv::CALIB_FIX_INTRINSIC, kConvergence);
  Eigen::Matrix3d r;
  for (int i = 0; i < 9; ++i) r(i / 3, i % 3) = rotation.at<double>(i / 3, i % 3);
  // OpenCV's stereo convention: X_cameraK = R X_camera0 + T.
  solution.T_camera0_camera =
      Pose(r, unit * Eigen::Vector3d(translation.at<double>(0), translation.at<double>(1), translation.at<double>(2)))
          .inverse();
  solution.via_projector = camera0.calibration.T_camera_projector * camera.calibration.T_camera_projector.inverse();
  return solution;
}

bool is_multi_camera_capture(const std::string& folder) {
  std::error_code error;
  return fs::is_directory(camera_folder(folder, 0), error);
}

std::vector<std::string> multi_camera_folders(const std::string& folder) {
  if (!is_multi_camera_capture(folder)) {
    throw_error(ErrorCode::kNotFound, "{}: no camera0 subfolder (a multi-camera capture has camera0, camera1, ...)",
                folder);
  }
  std::vector<std::string> folders;
  std::error_code error;
  while (folders.size() < static_cast<std::size_t>(ScannerCalibration::kMaxCameras) &&
         fs::is_directory(camera_folder(folder, folders.size()), error)) {
    folders.push_back(camera_folder(folder, folders.size()));
  }
  // A camera folder past the first gap is a layout error, not a camera to leave out silently.
  for (std::size_t k = folders.size() + 1; k <= static_cast<std::size_t>(ScannerCalibration::kMaxCameras); ++k) {
    if (fs::exists(camera_folder(folder, k), error)) {
      throw_error(ErrorCode::kInvalidArgument, "{}: {} is there but {} is missing (camera folders are numbered from 0 "
                  "without gaps)", folder, camera_folder(folder, k), camera_folder(folder, folders.size()));
    }
  }
  if (folders.size() < 2) {
    throw_error(ErrorCode::kInvalidArgument,
                "{}: only camera0 (a multi-camera capture has camera0 and camera1 at least; calibrate one camera with "
                "--input {})",
                folder, camera_folder(folder, 0));
  }
  return folders;
}

MultiCameraCalibrateResult calibrate_multi_camera_capture(const CalibrateCaptureOptions& options,
                                                          const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  MultiCameraCalibrateResult result;
  result.camera_folders = multi_camera_folders(options.input);
  // Every camera must hold the same board poses: checked before hours of work, not after.
  const std::size_t poses = board_pose_count(result.camera_folders.front());
  for (const std::string& folder : result.camera_folders) {
    const std::size_t count = board_pose_count(folder);
    if (count != poses) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: {} board poses, {} has {} (every camera's capture holds the same poses in the same order)",
                  folder, count, result.camera_folders.front(), poses);
    }
  }
  for (const std::string& folder : result.camera_folders) {
    CalibrateCaptureOptions camera_options = options;
    camera_options.input = folder;
    const std::string name = fs::path(folder).filename().string();
    const ProgressCallback camera_progress = [&progress, &name](const ProgressUpdate& update) {
      return !progress || progress({update.stage, update.done, update.total, name + ": " + update.detail});
    };
    try {
      result.cameras.push_back(calibrate_capture(camera_options, camera_progress));
    } catch (const Error& error) {
      // The camera's own message names its views; say which camera they are.
      if (std::string(error.what()).find(folder) != std::string::npos) throw;
      throw Error(error.code(), fmt::format("{}: {}", folder, error.what()));
    }
    const CalibrateCaptureResult& first = result.cameras.front();
    const CalibrateCaptureResult& camera = result.cameras.back();
    if (camera.views.size() != first.views.size()) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: {} board poses, {} has {} (every camera's capture holds the same poses in the same order)",
                  folder, camera.views.size(), result.camera_folders.front(), first.views.size());
    }
    for (std::size_t v = 0; v < camera.views.size(); ++v) {
      if (camera.views[v].name != first.views[v].name) {
        throw_error(ErrorCode::kInvalidArgument,
                    "{}: board pose {} is '{}', in {} it is '{}' (every camera's capture holds the same poses in the "
                    "same order)",
                    folder, v, camera.views[v].name, result.camera_folders.front(), first.views[v].name);
      }
    }
  }

  const CalibrateCaptureResult& first = result.cameras.front();
  result.calibration = first.procam.calibration;
  double squared_sum = 0.0;
  int corners = 0;
  const std::size_t pair_count = result.cameras.size() - 1;
  for (std::size_t k = 1; k < result.cameras.size(); ++k) {
    const CalibrateCaptureResult& camera = result.cameras[k];
    report_progress(progress, {"camera pairs", k - 1, pair_count,
                               fmt::format("{} against {}", fs::path(result.camera_folders[k]).filename().string(),
                                           fs::path(result.camera_folders.front()).filename().string())});
    try {
      result.pairs.push_back(
          calibrate_camera_pair(first.views, first.procam, camera.views, camera.procam, first.board));
    } catch (const Error& error) {
      throw Error(error.code(), fmt::format("{} against {}: {}", result.camera_folders[k],
                                            result.camera_folders.front(), error.what()));
    }
    const CameraPairSolution& pair = result.pairs.back();
    // stereoCalibrate's RMS is over both images' corners: 2 residuals per corner pair.
    squared_sum += pair.rms_px * pair.rms_px * 2.0 * pair.corners;
    corners += 2 * pair.corners;
    result.calibration.additional_cameras.push_back(
        {camera.procam.calibration.camera, pair.T_camera0_camera, camera.procam.camera_rms_px});
  }
  report_progress(progress, {"camera pairs", pair_count, pair_count, ""});
  result.camera_camera_rms_px = corners > 0 ? std::sqrt(squared_sum / corners) : 0.0;
  result.calibration.description +=
      fmt::format("; a head of {} cameras, camera-camera {:.3f} px RMS", result.cameras.size(),
                  result.camera_camera_rms_px);

  const fs::path truth_path = fs::path(options.input) / "groundtruth" / "calibration.yml";
  std::error_code error;
  if (fs::exists(truth_path, error)) {
    result.truth = read_calibration(truth_path.string());
    if (result.truth->camera_count() != static_cast<int>(result.cameras.size())) {
      throw_error(ErrorCode::kFormat, "{}: the exact calibration has {} cameras, the capture {}", truth_path.string(),
                  result.truth->camera_count(), result.cameras.size());
    }
    for (std::size_t k = 1; k < result.cameras.size(); ++k) {
      const Pose& exact = result.truth->additional_cameras[k - 1].T_camera0_camera;
      result.pair_errors.push_back(compare_poses(result.pairs[k - 1].T_camera0_camera, exact));
      result.pair_errors_via_projector.push_back(compare_poses(result.pairs[k - 1].via_projector, exact));
    }
  }
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace sls::calib
