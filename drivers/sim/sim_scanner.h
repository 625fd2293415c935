// The simulated scanner as devices: a camera, a projector and a turntable behind the driver
// interfaces of drivers/interfaces/, sharing one state, so the camera captures what the
// projector shows on the object at the turntable's angle. Opened by URI:
//   sim://knurled-screw?preset=demo&frames=120&seed=1&noise=1&device=cuda
// (object: knurled-screw, knurled-knob, chessboard, plane, sphere; preset: ci, demo, paper).
//
// A calibration target with a simulated operator, for a calibration capture through the
// devices (session::capture_calibration, `sls calibrate --camera`):
//   sim://chessboard?calibration=1&preset=ci&hand_poses=12&head=knurled-screw
// The head is the one set up for `head` (sim_calibration_capture.h: make_calibration_rig), its
// pattern set codes projector columns and rows, and the operator moves the calibration board
// (9 x 7 corners of 0.6 mm) as a person does: at every new acquisition (a camera's start(), one
// per pose of a calibration capture) to the next of `hand_poses` poses by hand, until the
// turntable is homed; from then on the board sits on the turntable's mount, and every capture
// sees it at the angle the table is at (any angle: in view or not, as on a real table).
// `frames`, `tilt` and `offset_um` (a scan's) are refused with calibration=1.
// `board` is the target, as `sls sim --calibration --board` spells it: chessboard (the
// default), or charuco[:COLSxROWS], OpenCV's ChArUco board (default 12 x 9 squares of 1.2 mm with
// 0.9 mm markers of DICT_5X5_100, larger than the field: views near its edges show part of it),
// posed as `sls sim --calibration --board charuco` poses it. Its markers come from calib: the
// opener hands in the board maker (open()'s charuco_board; drivers::OpenOptions).
//
// A head of several cameras (`sls sim --calibration --cameras N`'s, sim_calibration_capture.h):
//   sim://chessboard?calibration=1&preset=ci&hand_poses=12&cameras=2&camera=1
// is camera 1 of that head (camera: 0 .. cameras − 1, default 0), seeing the board poses and
// having the lens, sensor and place of `sls sim --calibration --cameras 2`'s camera1. The
// devices of one head — the URIs that differ only in `camera` — share the projector, the
// turntable and the operator: what the projector shows every camera sees, and the operator
// moves the board when an acquisition of the head starts (the first of its cameras started
// while none is), so cameras started together for one pose all see the same pose.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "drivers/interfaces/camera.h"
#include "drivers/interfaces/device_uri.h"
#include "drivers/interfaces/projector.h"
#include "drivers/interfaces/turntable.h"
#include "drivers/sim/renderer.h"

namespace sls::sim {

// The exposure time the rig's optics are set for (white_electrons: 70 % of the full well on
// a white target); the camera's set_exposure_us() scales the light it collects from this.
constexpr double kSimNominalExposureUs = 10000.0;

class SimScanner : public std::enable_shared_from_this<SimScanner> {
 public:
  // Throws sls::Error(kInvalidArgument) naming the URI's bad part (scheme, object, preset,
  // a query key it does not know); kUnsupported for board=charuco without `charuco_board`.
  static std::shared_ptr<SimScanner> open(const std::string& uri, const CharucoBoardMaker& charuco_board = {});
  static std::shared_ptr<SimScanner> create(const std::string& object, const RigOptions& rig_options,
                                            const Device& device);
  // The same with a scene made by the caller (e.g. a ChArUco board, make_chessboard_scene with
  // calib's marker table); the URI names it by scene.name().
  static std::shared_ptr<SimScanner> create(const Scene& scene, const RigOptions& rig_options, const Device& device);
  // A rig and scene built by the caller (a calibration capture: rig.placements, a board of
  // its own); `uri` names the device in recordings.
  static std::shared_ptr<SimScanner> create(SimRig rig, Scene scene, const Device& device, std::string uri);

  const std::string& uri() const { return uri_; }
  const SimRig& rig() const { return renderer_.rig(); }
  const Scene& scene() const { return renderer_.scene(); }

  std::unique_ptr<drivers::Camera> camera();
  std::unique_ptr<drivers::Projector> projector();
  std::unique_ptr<drivers::Turntable> turntable();

  // Calibration captures (rig().placements): the operator puts the object at placement
  // `frame`; the camera sees it there until the next call. A placement on the table is
  // captured only with the turntable moved to its commanded angle.
  void place_object(int frame);
  // Whether the scanner's simulated operator places the board itself (calibration=1 above).
  bool simulated_operator() const { return head_->hand_placements > 0; }

  // Where the camera's images go (drivers::Camera::set_image_memory).
  void set_image_memory(MemoryType memory);

  // The ground truth of the frame the turntable (or the operator) is at now.
  GroundTruthFrame ground_truth();
  // Depth-only mode: the noisy depth map of the current frame.
  Image32f depth_map();

 private:
  friend class SimCamera;
  friend class SimProjector;
  friend class SimTurntable;
  // What the devices of one head share (the header): the projector's DMD, the turntable, the
  // operator, and the lock that guards them and every camera's renderer.
  struct Head {
    std::mutex mutex;
    int pattern = -1;         // on the DMD; −1 = dark
    int step = 0;             // turntable position in steps
    int placement = -1;       // calibration captures: the placement; −1 = none yet
    int hand_placements = 0;  // the simulated operator's poses by hand (placements 0 ..); 0 = none
    int next_hand = 0;        // the next of them
    bool homed = false;
    int started_cameras = 0;  // cameras acquiring now
    // Counts changes of what the cameras see (the table's step, the placement): a camera whose
    // count differs starts its frame's captures (and their noise) afresh.
    std::uint64_t scene_changes = 0;
  };

  SimScanner(std::string uri, Renderer renderer, std::shared_ptr<Head> head = std::make_shared<Head>())
      : uri_(std::move(uri)), head_(std::move(head)), renderer_(std::move(renderer)) {}
  // The head state shared by the scanners whose URIs differ only in `camera` (a new one
  // when none of them is open).
  static std::shared_ptr<Head> shared_head(const std::string& key);

  // Renders the image a trigger produces now (under the lock).
  drivers::CapturedImage capture();
  // The frame the camera sees: the turntable's step in a scan, the placement in a calibration
  // capture. Traces it when it changed.
  int ensure_frame_traced();
  // The simulated operator (under the lock): a camera's start() is a new pose; the board on
  // the table is the placement at the table's step (added when the step is new).
  // `others_acquiring`: whether another camera of the head is started (then the board stays).
  void start_acquisition(bool others_acquiring);
  int table_placement_locked();
  void scene_changed_locked() { ++head_->scene_changes; }

  std::string uri_;
  std::shared_ptr<Head> head_;
  Renderer renderer_;
  int camera_index_ = 0;      // in its head
  std::uint64_t scene_changes_seen_ = 0;
  std::uint32_t captures_in_frame_ = 0;
  double exposure_scale_ = 1.0;  // the camera's exposure / kSimNominalExposureUs
  std::uint64_t frame_id_ = 0;
};

}  // namespace sls::sim
