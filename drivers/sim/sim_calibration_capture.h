// The simulator's calibration capture (issue #17): a chessboard (or a ChArUco board, whose
// views may show part of it: SimCalibrationOptions::board) shown to the simulated
// scanner in varied poses "by hand" (turntable at 0°, manifest angle null), then on a fixed
// mount on the turntable at several commanded angles (for the axis), captured through the
// devices with a pattern set coding projector columns and rows. The recording is made
// uncalibrated (no calibration.yml); groundtruth/ holds the exact calibration:
//   calibration.yml    write_calibration(rig.calibration()): camera, projector, their pose,
//                      the turntable axis in the camera frame
//   board.json         the board and its frame (below)
//   board_poses.txt    T_camera_board per frame (board frame -> camera frame), TUM format
//                      (sdk/core/trajectory.h), timestamps = the frames' timestamps
//   capture.json       per frame: index, kind (hand | turntable), commanded and true angle
//   scene.json, rig.json   as a scan's (rig.json's T_table_object: the turntable mount)
//   frames/NNNNNN/corners.json   exact camera and projector pixels of every inner corner
//   frames/NNNNNN/     depth.pfm, projector_u.pfm, projector_v.pfm, valid.png,
//                      depth_sigma.pfm, as a scan's (drivers/sim/sim_recording.h)
//
// Board frame (OpenCV's object points): origin at the inner corner that appears top-left
// when the board faces the camera upright, x along the rows (image right), y down the board
// (image down), z into the board (away from the printed face); corner k = (i s, j s, 0) with
// i = k mod cols, j = k div cols. docs/simulator.md has the poses and the file formats.
#pragma once

#include <string>
#include <vector>

#include "drivers/sim/rig.h"
#include "drivers/sim/scene.h"
#include "drivers/sim/sim_recording.h"
#include "sdk/core/device.h"
#include "sdk/core/pose.h"
#include "sdk/core/progress.h"

namespace sls::sim {

// The default target: 9 x 7 inner corners of 0.6 mm squares with a light border of one
// square (7.2 x 6.0 mm in all), so the whole plate stays inside the 12 x 9 mm field and the
// projector's light at every pose while a square still spans 20 camera pixels at ci.
ChessboardParameters calibration_board();
// The default ChArUco target's geometry: 12 x 9 squares of 1.2 mm (11 x 8 inner corners, 14.4 x
// 10.8 mm of squares), larger than the 12 x 9 mm field, so views near the field's edges are
// partial (only its central half must stay in view); a square spans 40 camera pixels at ci.
// Its markers (CharucoPattern) come from calib (OpenCV's dictionary): `sls sim --calibration
// --board charuco` fills them, with 0.9 mm markers of DICT_5X5_100 by default.
ChessboardParameters charuco_calibration_board_geometry();

// The turntable's stepper for a calibration capture: 6400 steps (a 200-step motor at 1/32
// microstepping, as the head controller's); commanded angles are whole steps.
constexpr int kCalibrationTurntableSteps = 6400;

// A simulated head has one to four cameras round the projector, each at the triangulation
// angle from it: camera 0 to its left (the scan's camera), 1 to its right (mirroring 0 across
// it), 2 above it and 3 below it.
constexpr int kMaxSimCalibrationCameras = 4;

struct SimCalibrationOptions {
  // Preset, camera width, projector, bit depth, gamma, turntable jitter, seed, noise. The
  // scan's frames per revolution and object mount (tilt, offset) do not apply.
  RigOptions rig;
  int hand_poses = 12;     // frames 0 .. hand_poses − 1
  int turntable_poses = 7; // then these, at angles spread over up to −40° .. +40° (as far as
                           // the board stays in view)
  // The object the head is set up for: camera and projector stand where a scan of it puts
  // them (focused on its surface), so the turntable axis calibrated here is the one its scans
  // use; the turntable views' board stands at that focus. "chessboard": focused on the axis.
  std::string head_object = "knurled-screw";
  ChessboardParameters board = calibration_board();
  // Cameras of the head (1 .. kMaxSimCalibrationCameras). With 2 the second camera stands
  // twice the triangulation angle round from the first (the projector halfway between them);
  // a third and a fourth stand above and below the projector, the triangulation angle up and
  // down from it. Every board then faces the projector and stays in view of every camera (the
  // hand poses depend on the count), and the capture is one recording per camera (the layout
  // below). One and two cameras give what they gave before the others existed, bit for bit.
  int cameras = 1;
};

// The board frame above in the scene's object frame (scene.json's frame).
Pose board_frame_in_object(const ChessboardParameters& board);

// The rigs of the capture, one per camera (each that camera with the same projector): one
// placement per frame (hand poses, then turntable poses, the same for every camera), the
// column-and-row pattern set, kCalibrationTurntableSteps. Throws sls::Error
// (kInvalidArgument) for bad counts, or when some pose puts part of the board outside a
// camera's image or the projector's light, or turns it away from either.
std::vector<SimRig> make_calibration_rigs(const SimCalibrationOptions& options);
// The first camera's (of a one-camera head: the only one).
SimRig make_calibration_rig(const SimCalibrationOptions& options, const Scene& board);
// The exact calibration of the head: the first camera's, with the others as additional
// cameras (their intrinsics, T_camera0_cameraK).
ScannerCalibration head_calibration(const std::vector<SimRig>& rigs);

// Writes the capture to `folder` (created; must not exist or be empty). Every frame is
// flushed as it is captured; its ground truth is written just before it, so an interrupted
// run leaves a valid recording whose frames all have their ground truth. Throws sls::Error.
// A head of several cameras writes one such recording per camera into `folder`/camera0,
// `folder`/camera1 (each with the truth of that camera and the projector), and the head's
// exact calibration (head_calibration) as `folder`/groundtruth/calibration.yml; the summary
// is camera 0's with that groundtruth folder.
SimRecordingSummary write_sim_calibration_recording(const std::string& folder, const SimCalibrationOptions& options,
                                                    const Device& device, const ProgressCallback& progress);

}  // namespace sls::sim
