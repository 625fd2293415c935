#include "drivers/sim/sim_scanner.h"

#include <cmath>
#include <map>
#include <set>
#include <string>

#include <fmt/format.h>

#include "drivers/sim/sim_calibration_capture.h"
#include "sdk/core/error.h"

namespace sls::sim {

// Simulated time: the paper's scanner runs at about 3 frames (pattern stacks) per second.
constexpr std::int64_t kStackPeriodNs = 333'333'333;

class SimCamera final : public drivers::Camera {
 public:
  explicit SimCamera(std::shared_ptr<SimScanner> scanner) : scanner_(std::move(scanner)) {}

  drivers::CameraInfo info() const override {
    const SimRig& rig = scanner_->rig();
    return {scanner_->uri(), "slscan simulated camera", "SIM-CAM-" + std::to_string(scanner_->camera_index_),
            rig.camera.width, rig.camera.height, rig.optics.camera_sensor.bit_depth};
  }
  void set_exposure_us(double exposure_us) override {
    if (!(exposure_us > 0.0)) throw_error(ErrorCode::kInvalidArgument, "exposure {} us must be positive", exposure_us);
    exposure_us_ = exposure_us;
    // The rig's optics (white_electrons, ambient) are for the nominal exposure; others scale
    // the light collected (HDR capture).
    std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
    scanner_->exposure_scale_ = exposure_us / kSimNominalExposureUs;
  }
  double exposure_us() const override { return exposure_us_; }
  std::optional<ScannerCalibration> exact_calibration() const override { return scanner_->rig().calibration(); }
  void set_trigger_source(drivers::TriggerSource source) override { source_ = source; }
  ~SimCamera() override { stop(); }
  void start() override {
    {
      std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
      const bool others_acquiring = scanner_->head_->started_cameras > (started_ ? 1 : 0);
      scanner_->start_acquisition(others_acquiring);
      if (!started_) ++scanner_->head_->started_cameras;
    }
    started_ = true;
  }
  void stop() override {
    if (started_) {
      std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
      --scanner_->head_->started_cameras;
    }
    started_ = false;
    pending_ = 0;
  }
  void software_trigger() override {
    if (!started_) throw_error(ErrorCode::kInvalidArgument, "{}: software trigger before start()", scanner_->uri());
    ++pending_;
  }
  void set_image_memory(MemoryType memory) override {
    drivers::Camera::set_image_memory(memory);
    scanner_->set_image_memory(memory);
  }
  drivers::CapturedImage wait_image(std::chrono::milliseconds timeout) override {
    if (!started_ || pending_ == 0) {
      throw_error(ErrorCode::kTimeout, "{}: no image within {} ms (camera not started or not triggered)",
                  scanner_->uri(), timeout.count());
    }
    --pending_;
    return scanner_->capture();
  }

 private:
  std::shared_ptr<SimScanner> scanner_;
  double exposure_us_ = kSimNominalExposureUs;
  drivers::TriggerSource source_ = drivers::TriggerSource::kSoftware;
  bool started_ = false;
  int pending_ = 0;
};

class SimProjector final : public drivers::Projector {
 public:
  explicit SimProjector(std::shared_ptr<SimScanner> scanner)
      : scanner_(std::move(scanner)), patterns_(scanner_->rig().patterns) {}

  drivers::ProjectorInfo info() const override {
    const SimRig& rig = scanner_->rig();
    return {scanner_->uri(), "slscan simulated DLPC350", "sim", rig.projector.width, rig.projector.height};
  }
  void load_patterns(const PatternSet& patterns) override {
    validate_pattern_set(patterns);
    // The rig renders its own set: the simulated DMD holds exactly that LUT.
    if (patterns != scanner_->rig().patterns) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: the simulated projector shows the rig's pattern set '{}', not '{}'", scanner_->uri(),
                  scanner_->rig().patterns.name, patterns.name);
    }
    patterns_ = patterns;
  }
  const PatternSet& patterns() const override { return patterns_; }
  void show_pattern(int index) override {
    if (index < 0 || static_cast<std::size_t>(index) >= patterns_.size()) {
      throw_error(ErrorCode::kInvalidArgument, "{}: pattern {} of a set of {}", scanner_->uri(), index,
                  patterns_.size());
    }
    std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
    scanner_->head_->pattern = index;
  }
  int current_pattern() const override {
    std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
    return scanner_->head_->pattern;
  }
  void go_dark() override {
    std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
    scanner_->head_->pattern = -1;
  }

 private:
  std::shared_ptr<SimScanner> scanner_;
  PatternSet patterns_;
};

class SimTurntable final : public drivers::Turntable {
 public:
  explicit SimTurntable(std::shared_ptr<SimScanner> scanner) : scanner_(std::move(scanner)) {}

  void home(std::chrono::milliseconds) override {
    std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
    scanner_->head_->homed = true;
    move_locked(0);
  }
  // The simulated stepper moves in whole steps of 360° / steps_per_revolution; angles beyond
  // 360° continue into the next revolution (frames k ≥ N), as a table turning on does.
  void move_to_deg(double angle_deg, std::chrono::milliseconds) override {
    if (!std::isfinite(angle_deg) || angle_deg < 0.0) {
      throw_error(ErrorCode::kInvalidArgument, "{}: turntable angle {} must be finite and >= 0", scanner_->uri(),
                  angle_deg);
    }
    std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
    if (!scanner_->head_->homed) throw_error(ErrorCode::kInvalidArgument, "{}: turntable not homed", scanner_->uri());
    const double steps = angle_deg / 360.0 * steps_per_revolution();
    move_locked(static_cast<int>(std::lround(steps)));
  }
  double position_deg() const override {
    std::lock_guard<std::mutex> lock(scanner_->head_->mutex);
    return scanner_->rig().step_angle_deg(scanner_->head_->step);
  }
  int steps_per_revolution() const override { return scanner_->rig().turntable.steps_per_revolution; }

 private:
  void move_locked(int step) {
    if (step != scanner_->head_->step) {
      scanner_->head_->step = step;
      scanner_->scene_changed_locked();
    }
  }
  std::shared_ptr<SimScanner> scanner_;
};

std::shared_ptr<SimScanner> SimScanner::create(const std::string& object, const RigOptions& rig_options,
                                               const Device& device) {
  return create(make_scene(object), rig_options, device);
}

std::shared_ptr<SimScanner> SimScanner::create(const Scene& scene, const RigOptions& rig_options,
                                               const Device& device) {
  const std::string& object = scene.name();
  SimRig rig = make_rig(rig_options, scene);
  if (!surface_material_by_name(rig_options.material.c_str(), &rig.material)) {
    throw_error(ErrorCode::kInvalidArgument, "unknown material '{}' (expected painted or metal)", rig_options.material);
  }
  std::string uri = "sim://" + object + "?preset=" + rig_options.preset +
                    "&frames=" + std::to_string(rig.turntable.steps_per_revolution) +
                    "&seed=" + std::to_string(rig_options.seed) + "&noise=" + (rig_options.noise ? "1" : "0") +
                    "&projector=" + rig_options.projector;
  // Only when not the default: the URIs of existing recordings stay what they were.
  if (rig_options.material != "painted") uri += "&material=" + rig_options.material;
  Renderer renderer(std::move(rig), scene, device);
  return std::shared_ptr<SimScanner>(new SimScanner(std::move(uri), std::move(renderer)));
}

std::shared_ptr<SimScanner> SimScanner::create(SimRig rig, Scene scene, const Device& device, std::string uri) {
  Renderer renderer(std::move(rig), std::move(scene), device);
  return std::shared_ptr<SimScanner>(new SimScanner(std::move(uri), std::move(renderer)));
}

std::shared_ptr<SimScanner> SimScanner::open(const std::string& text, const CharucoBoardMaker& charuco_board) {
  const drivers::DeviceUri uri = drivers::parse_device_uri(text);
  if (uri.scheme != "sim") throw_error(ErrorCode::kInvalidArgument, "'{}' is not a sim:// URI", text);
  static const std::set<std::string> kKeys = {"preset", "frames",  "seed",   "noise", "device", "width",
                                              "projector", "bits", "gamma", "jitter", "tilt",  "offset_um",
                                              "calibration", "hand_poses", "head", "material", "cameras", "camera",
                                              "board"};
  for (const auto& [key, value] : uri.query) {
    if (kKeys.count(key) == 0) {
      throw_error(ErrorCode::kInvalidArgument, "{}: unknown option '{}' (known: preset, frames, seed, noise, device, width, projector, bits, gamma, jitter, tilt, offset_um, calibration, hand_poses, head, cameras, camera, board, material)",
                  text, key);
    }
  }
  const bool calibration = uri.get_int("calibration", 0) != 0;
  for (const char* key : {"hand_poses", "head", "cameras", "camera", "board"}) {
    if (!calibration && uri.query.count(key) != 0) {
      throw_error(ErrorCode::kInvalidArgument, "{}: '{}' is an option of a calibration target (calibration=1)", text, key);
    }
  }
  RigOptions options;
  options.preset = uri.get("preset", "demo");
  options.frames = uri.get_int("frames", 0);
  options.camera_width = uri.get_int("width", 0);
  options.seed = static_cast<std::uint64_t>(uri.get_int("seed", 1));
  options.noise = uri.get_int("noise", 1) != 0;
  options.projector = uri.get("projector", "dlpc350");
  options.material = uri.get("material", options.material);
  options.bit_depth = uri.get_int("bits", options.bit_depth);
  options.gamma = uri.get_double("gamma", options.gamma);
  options.angle_jitter_deg = uri.get_double("jitter", options.angle_jitter_deg);
  options.mount_tilt_deg = uri.get_double("tilt", options.mount_tilt_deg);
  options.mount_offset_m = uri.get_double("offset_um", options.mount_offset_m * 1e6) * 1e-6;
  const std::string device_text = uri.get("device", default_device().to_string());
  if (!calibration) return create(uri.target, options, parse_device(device_text));

  // The calibration target with its simulated operator (the header).
  if (uri.target != "chessboard") {
    throw_error(ErrorCode::kInvalidArgument, "{}: a calibration target (calibration=1) is sim://chessboard, not '{}'",
                text, uri.target);
  }
  for (const char* key : {"frames", "tilt", "offset_um"}) {
    if (uri.query.count(key) != 0) {
      throw_error(ErrorCode::kInvalidArgument, "{}: '{}' is a scan's option, not a calibration target's", text, key);
    }
  }
  SimCalibrationOptions calibration_options;
  calibration_options.rig = options;
  calibration_options.hand_poses = uri.get_int("hand_poses", calibration_options.hand_poses);
  calibration_options.turntable_poses = 0;  // the board on the table goes where the table does
  calibration_options.head_object = uri.get("head", calibration_options.head_object);
  if (calibration_options.hand_poses < 1 || calibration_options.hand_poses > 1000) {
    throw_error(ErrorCode::kInvalidArgument, "{}: hand_poses={} (1 .. 1000)", text, calibration_options.hand_poses);
  }
  calibration_options.cameras = uri.get_int("cameras", 1);
  if (calibration_options.cameras < 1 || calibration_options.cameras > kMaxSimCalibrationCameras) {
    throw_error(ErrorCode::kInvalidArgument, "{}: cameras={} (the simulated head has 1 .. {})", text,
                calibration_options.cameras, kMaxSimCalibrationCameras);
  }
  const int camera = uri.get_int("camera", 0);
  if (camera < 0 || camera >= calibration_options.cameras) {
    throw_error(ErrorCode::kInvalidArgument, "{}: camera={} is not a camera of a head of {} (0 .. {}{})", text, camera,
                calibration_options.cameras, calibration_options.cameras - 1,
                uri.query.count("cameras") == 0 ? "; cameras=N says how many the head has" : "");
  }
  const std::string board_spec = uri.get("board", "chessboard");
  if (board_spec.rfind("charuco", 0) == 0) {
    if (!charuco_board) {
      throw_error(ErrorCode::kUnsupported,
                  "{}: board={} needs the ChArUco markers of calib (OpenCV), which the opener did not provide", text,
                  board_spec);
    }
    try {
      calibration_options.board = charuco_board(board_spec, charuco_calibration_board_geometry());
    } catch (const Error& error) {
      throw Error(error.code(), fmt::format("{}: board={}: {}", text, board_spec, error.what()));
    }
  } else if (board_spec != "chessboard") {
    throw_error(ErrorCode::kInvalidArgument, "{}: board={} (chessboard, charuco or charuco:COLSxROWS)", text,
                board_spec);
  }
  Scene board = make_chessboard_scene(calibration_options.board);
  // The head's geometry and poses depend on its camera count (every pose in view of all).
  SimRig rig = make_calibration_rigs(calibration_options)[static_cast<std::size_t>(camera)];
  drivers::DeviceUri head_uri = uri;
  head_uri.query.erase("camera");
  std::shared_ptr<Head> head = shared_head(head_uri.to_string());
  Renderer renderer(std::move(rig), std::move(board), parse_device(device_text));
  std::shared_ptr<SimScanner> scanner(new SimScanner(text, std::move(renderer), head));
  scanner->camera_index_ = camera;
  std::lock_guard<std::mutex> lock(head->mutex);
  head->hand_placements = calibration_options.hand_poses;
  return scanner;
}

std::shared_ptr<SimScanner::Head> SimScanner::shared_head(const std::string& key) {
  static std::mutex mutex;
  static std::map<std::string, std::weak_ptr<Head>> heads;
  std::lock_guard<std::mutex> lock(mutex);
  for (auto it = heads.begin(); it != heads.end();) {  // forget heads nobody holds
    it = it->second.expired() ? heads.erase(it) : std::next(it);
  }
  if (std::shared_ptr<Head> head = heads[key].lock()) return head;
  auto head = std::make_shared<Head>();
  heads[key] = head;
  return head;
}

std::unique_ptr<drivers::Camera> SimScanner::camera() { return std::make_unique<SimCamera>(shared_from_this()); }
std::unique_ptr<drivers::Projector> SimScanner::projector() {
  return std::make_unique<SimProjector>(shared_from_this());
}
std::unique_ptr<drivers::Turntable> SimScanner::turntable() {
  return std::make_unique<SimTurntable>(shared_from_this());
}

void SimScanner::place_object(int frame) {
  std::lock_guard<std::mutex> lock(head_->mutex);
  if (rig().placements.empty()) {
    throw_error(ErrorCode::kInvalidArgument, "{}: a scan's object stays on the turntable (no placements)", uri_);
  }
  if (frame < 0 || static_cast<std::size_t>(frame) >= rig().placements.size()) {
    throw_error(ErrorCode::kInvalidArgument, "{}: placement {} of {}", uri_, frame, rig().placements.size());
  }
  if (frame != head_->placement) {
    head_->placement = frame;
    scene_changed_locked();
  }
}

void SimScanner::start_acquisition(bool others_acquiring) {
  Head& head = *head_;
  // No operator, or the board is on the table, or the head's acquisition has begun (this
  // camera is one more of a pose's cameras).
  if (head.hand_placements == 0 || head.homed || others_acquiring) return;
  if (head.next_hand >= head.hand_placements) {
    throw_error(ErrorCode::kInvalidArgument,
                "{}: the simulated operator has placed the board at all of its {} poses by hand (hand_poses={})", uri_,
                head.hand_placements, head.hand_placements);
  }
  head.placement = head.next_hand++;
  scene_changed_locked();
}

int SimScanner::table_placement_locked() {
  const std::vector<ObjectPlacement>& placements = rig().placements;
  const double steps = rig().turntable.steps_per_revolution;
  for (std::size_t i = static_cast<std::size_t>(head_->hand_placements); i < placements.size(); ++i) {
    if (std::lround(*placements[i].commanded_angle_deg / 360.0 * steps) == head_->step) return static_cast<int>(i);
  }
  return renderer_.add_placement({rig().step_angle_deg(head_->step), rig().T_table_object});
}

int SimScanner::ensure_frame_traced() {
  if (scene_changes_seen_ != head_->scene_changes) {  // the table moved or the board did
    scene_changes_seen_ = head_->scene_changes;
    captures_in_frame_ = 0;
  }
  int frame = head_->step;
  if (head_->hand_placements > 0 && head_->homed) {
    frame = table_placement_locked();
    if (frame != renderer_.frame()) captures_in_frame_ = 0;  // the board just went onto the table
  } else if (!rig().placements.empty()) {
    if (head_->placement < 0) throw_error(ErrorCode::kInvalidArgument, "{}: capture before place_object()", uri_);
    frame = head_->placement;
    const std::optional<double>& angle = rig().placements[static_cast<std::size_t>(frame)].commanded_angle_deg;
    // The table carries the board only where it was commanded to: compare whole steps.
    const double steps = rig().turntable.steps_per_revolution;
    if (angle && std::lround(*angle / 360.0 * steps) != head_->step) {
      throw_error(ErrorCode::kInvalidArgument, "{}: turntable at {}°, placement {} needs it at {}°", uri_,
                  rig().step_angle_deg(head_->step), frame, *angle);
    }
  }
  if (renderer_.frame() != frame) renderer_.set_frame(frame);
  return frame;
}

void SimScanner::set_image_memory(MemoryType memory) {
  std::lock_guard<std::mutex> lock(head_->mutex);
  renderer_.set_image_memory(memory);
}

drivers::CapturedImage SimScanner::capture() {
  std::lock_guard<std::mutex> lock(head_->mutex);
  const int frame = ensure_frame_traced();
  drivers::CapturedImage captured;
  PatternDesc dark;
  dark.kind = PatternKind::kBlack;
  const PatternDesc& shown =
      head_->pattern >= 0 ? rig().patterns.patterns[static_cast<std::size_t>(head_->pattern)] : dark;
  captured.image = renderer_.render(shown, captures_in_frame_, exposure_scale_);
  const std::uint32_t images = static_cast<std::uint32_t>(rig().patterns.size());
  captured.timestamp_ns = frame * kStackPeriodNs +
                          static_cast<std::int64_t>(captures_in_frame_) * (kStackPeriodNs / (images > 0 ? images : 1));
  captured.frame_id = frame_id_++;
  ++captures_in_frame_;
  return captured;
}

GroundTruthFrame SimScanner::ground_truth() {
  std::lock_guard<std::mutex> lock(head_->mutex);
  ensure_frame_traced();
  return renderer_.ground_truth();
}

Image32f SimScanner::depth_map() {
  std::lock_guard<std::mutex> lock(head_->mutex);
  ensure_frame_traced();
  return renderer_.render_depth();
}

}  // namespace sls::sim
