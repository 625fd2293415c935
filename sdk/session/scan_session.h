// The scan session (paper section II, DESIGN.md section 1): per frame
//   decode (pattern stack -> depth) -> track (ICP against the model raycast from the last pose)
//   -> integrate (TSDF / GTSDF) -> move the volume (resample, ship what leaves) -> raycast
// for any source of frames: a recording (replay, or the simulator's capture), or frames pushed
// live from the capture sequencer's per-frame callback. The CPU or one CUDA GPU, per stage
// timings, a report per frame (the payload of the C API's per-frame callback).
//
//   ScanSession session(calibration, &patterns, options);
//   for each frame: FrameReport r = session.add_frame(frame);   // never throws for a bad frame
//   fusion::ExtractedSurface model = session.final_surface();
//
// Frames. World = the camera frame of the first fused frame (the tracker knows nothing else),
// unless frames carry known poses (ground truth, a robot): then world is theirs.
// A frame that cannot be read or decoded is `kSkipped`, one the tracker cannot register is
// `kLost`; neither touches the model, and the scan goes on. The model fused so far is always
// valid: final_surface() may be called at any time (after an interruption too).
// Thread safety: one thread drives a session; prefetch() alone may run beside it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "fusion/extract.h"
#include "fusion/integrator.h"
#include "fusion/moving_volume.h"
#include "fusion/tracker.h"
#include "fusion/volume.h"
#include "sdk/core/calibration.h"
#include "sdk/core/device.h"
#include "sdk/core/image.h"
#include "sdk/core/pose.h"
#include "sdk/core/progress.h"
#include "sdk/core/recording.h"
#include "sdk/core/trajectory.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/session/scan_deformation.h"

namespace sls::session {

// What a CUDA session allocates on the GPU after its moving volume is placed, per camera pixel
// (tracker pyramids, raycasts, the deformation's reference and last frame, the next stack's
// upload slot, a move's shipping), beside the volume and the integrator's lists
// (fusion::integration_gpu_bytes), for sizing the volume under ScanSessionOptions::max_gpu_bytes.
// An upper bound of what was measured at the paper's size (docs/benchmarks.md, "A GPU memory
// budget").
constexpr double kGpuBytesPerPixelAfterPlacement = 96.0;

// What a moving volume's later passes over surface it already shipped ship (fusion/
// revisit_filter.h). A session that circles the object again and again fuses the same surface
// on every pass; kept, each pass adds a copy and a long session's model grows without bound.
enum class RevisitPolicy {
  kKeep,   // every pass is shipped (a second revolution adds a second copy)
  kMerge,  // only surface no earlier move shipped, from the first move on
  // Every pass until the scan has turned one revolution and one move's rotation
  // (moving.max_rotation_deg) more, then merged: a single revolution keeps its seam's second
  // pass, which the loop closure's deformation aligns, and is shipped exactly as kKeep ships it;
  // a longer session's model stays bounded by the object's surface. "Turned": the turntable's
  // angle from the first fused frame, or without angles the rotation of the camera's fused
  // poses summed frame to frame.
  kAfterFirstRevolution,
};
const char* revisit_policy_name(RevisitPolicy policy);  // "keep", "merge", "auto"
// The policy of a name revisit_policy_name() gives; sls::Error(kInvalidArgument) for another.
RevisitPolicy parse_revisit_policy(const std::string& name);

struct ScanSessionOptions {
  Device device = Device::cpu();
  fusion::IntegrationOptions integration = fusion::IntegrationOptions::gtsdf();
  fusion::TrackingOptions tracking;  // photometric_weight > 0: with the frames' textures (ScanFrame::texture)
  DecodeOptions decode;
  fusion::VoxelFormat voxel_format = fusion::VoxelFormat::kCompact;
  // The moving volume, sized at the first fused frame: its extent (0: the camera's field of
  // view at the focus distance across, half its width deep) and voxel size (0: two pixel
  // footprints at the focus distance, grown until one buffer holds at most max_voxels).
  Eigen::Vector3d volume_size_m = Eigen::Vector3d::Zero();
  double voxel_size_m = 0.0;
  double max_voxels = 64e6;
  // A GPU memory budget in bytes for what slscan allocates on the GPU (gpu_allocations(); 0:
  // none), e.g. 6e9 for an 8 GB Jetson Orin beside its OS. A CUDA session sizes its moving
  // volume at the first fused frame so that both buffers fit beside what is already allocated
  // and the buffers still to come (kGpuBytesPerPixelAfterPlacement per camera pixel, the
  // integrator's lists):
  // an automatic voxel size grows, a given one keeps its size and the volume's extent shrinks.
  // Under 64 voxels a side, the first add_frame() throws sls::Error(kOutOfMemory) saying what
  // the budget leaves room for. A fixed volume is not sized by it. Ignored on the CPU.
  double max_gpu_bytes = 0.0;
  fusion::MovingVolumeOptions moving;  // focus_distance_m <= 0: the first frame's median depth
  // On a GPU, a move's surface ships beside the frame loop (MovingVolumeOptions::
  // ship_in_background; FrameReport::shipped), collected before the next keyframe or move: the
  // same model and poses either way. Ignored on the CPU, where it would share the frame loop's
  // cores; moving.ship_in_background is set from this.
  bool ship_in_background = true;
  // Revisited surface (RevisitPolicy). kMerge sets moving.merge_revisits; kKeep and
  // kAfterFirstRevolution leave it as it is (kAfterFirstRevolution merges from its turn on).
  RevisitPolicy revisits = RevisitPolicy::kAfterFirstRevolution;
  // Instead, one fixed volume (e.g. around a known object for ground-truth poses): no moves.
  std::optional<fusion::VolumeGeometry> fixed_volume;
  // Use the recording's turntable angles with the calibration's axis as the pose guess (the
  // constructor refuses it for a calibration without an axis).
  bool turntable_prior = false;
  // Check each tracked motion against the turntable's (the recording's angles about the
  // calibration's axis, when both exist; with or without the prior): a frame whose tracked
  // rotation since the last fused frame differs from the turntable's by more than a quarter of
  // the step (at least 0.1°, at most 2°) is lost: the tracker slid along a symmetry (a surface
  // of revolution turning about its own axis) or locked onto the wrong surface.
  bool verify_with_turntable = true;
  // Online deformation (paper section IV, scan_deformation.h) of tracked scans into a moving
  // volume; with it, close_loop(). Off for known poses or a fixed volume (no drift to correct).
  DeformationOptions deformation;
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate() const;
};

// The voxels of one moving-volume buffer that options.max_gpu_bytes leaves room for: both
// buffers and the integrator's lists for them (fusion::integration_gpu_bytes), beside
// `held_bytes` already allocated and `later_bytes` still to come. Infinity without a budget or
// on the CPU.
double gpu_budget_voxels(const ScanSessionOptions& options, double held_bytes, double later_bytes);

// One frame in: a pattern stack to decode, or a depth map; what the source knows about it.
struct ScanFrame {
  int index = 0;
  std::int64_t timestamp_ns = 0;
  std::optional<double> turntable_angle_deg;
  std::vector<Image16u> images;            // a pattern stack (the session's pattern set), or
  // the same stack shared read-only with a live capture's recording writer, which writes it
  // while the session fuses it (recording_writer_thread.h: no copy of a 0.5 GB stack); used
  // when `images` is empty. pattern_images() is whichever the frame holds.
  std::shared_ptr<const std::vector<Image16u>> shared_images;
  std::optional<Image32f> depth_m;         // a depth map (camera-frame z, 0 = none)
  // The grey texture for the tracker's photometric term (options.tracking.photometric_weight
  // > 0, else unused): linear intensity at the camera's size. Empty: a pattern stack's white −
  // black (white − the black level without a black pattern; none without a white one), and
  // none for a depth map (the term is then off for the frame).
  std::optional<Image32f> texture;
  std::optional<Pose> known_T_world_camera;  // fuse here instead of tracking (ground truth)
  std::string problem;                     // non-empty: the source could not deliver the frame
  double read_ms = 0.0;                    // the source's time to deliver it (for the report)

  const std::vector<Image16u>& pattern_images() const {
    return images.empty() && shared_images ? *shared_images : images;
  }
};

enum class FrameStatus { kFused, kLost, kSkipped };
const char* frame_status_name(FrameStatus status);

// Milliseconds per stage (a frame's, or totals).
struct StageTimes {
  double read_ms = 0.0;  // the source's (ScanFrame::read_ms)
  double decode_ms = 0.0;
  double track_ms = 0.0;
  double integrate_ms = 0.0;
  double move_ms = 0.0;
  double raycast_ms = 0.0;
  double deform_ms = 0.0;  // the frame loop's share of online deformation (samples, queueing);
                           // the graph's solves run beside it (FrameDeformation::solve_ms)
  double total_ms() const {
    return read_ms + decode_ms + track_ms + integrate_ms + move_ms + raycast_ms + deform_ms;
  }
  StageTimes& operator+=(const StageTimes& other);
};

// Online deformation as a frame saw it: whether the frame made a keyframe (a graph node), and
// the graph as the worker had it then (it solves beside the frame loop, a little behind).
struct FrameDeformation {
  bool keyframe = false;
  std::size_t nodes = 0;
  std::size_t constraints = 0;
  std::size_t pending = 0;      // keyframes and shipped parts the worker had still to do
  double solve_ms = 0.0;        // the worker's last keyframe job (match + Gauss–Newton)
};

struct FrameReport {
  int index = 0;
  std::int64_t timestamp_ns = 0;
  FrameStatus status = FrameStatus::kSkipped;
  std::string reason;                  // why skipped or lost (or fused unverified)
  // Fused at the turntable prior because tracking could not verify the pose: too little of the
  // view overlaps the model (after a skipped frame, say). Without it the scan would lose every
  // later frame too, as the model would no longer reach the next views.
  bool unverified = false;
  Pose T_world_camera;                 // fused pose (the guess for a lost frame)
  std::size_t depth_pixels = 0;        // valid depth pixels
  std::optional<fusion::TrackingResult> tracking;  // absent for the first frame and known poses
  fusion::IntegrationStats integration;
  fusion::MoveStats move;
  // On a GPU a move's surface ships beside the frame loop (move.shipping): its figures come
  // with the frame that collected it (before the next keyframe or move), here.
  std::optional<fusion::MoveStats> shipped;
  FrameDeformation deformation;
  StageTimes times;

  // The ship whose figures (shipped_*, ship_*) this frame gives: its move's when that shipped
  // before returning, else one collected here; null when neither.
  const fusion::MoveStats* ship() const {
    if (shipped) return &*shipped;
    return move.moved && !move.shipping ? &move : nullptr;
  }
};

// What close_loop() did: the last fused frames (DeformationOptions::loop_frames) registered
// (ICP) to the first frame's surface (the model raycast from the first pose before the volume
// first moved), their points made E_con terms to where those registrations put them, and the
// graph solved.
struct LoopClosureReport {
  int first_frame = 0;
  int last_frame = 0;
  // Of the newest kept frame that registers (the last frame unless it did not) to the first
  // frame's surface.
  fusion::TrackingResult registration;
  std::vector<int> registered_frames;     // the kept frames that registered, newest first
  std::vector<std::pair<int, std::string>> unregistered;  // those that did not, and why
  // How far that registration moved the frame from its guess (the turntable's pose with the
  // prior, else the online deformation's estimate).
  double guess_moved_m = 0.0, guess_moved_deg = 0.0;
  // The table's repeatability (TurntableAxis::angle_sigma_deg, tilt_sigma_deg) when its motion
  // was the registrations' pose prior (fusion/pose_prior.h: the rotation about the axis and
  // across it, σ √2 times these), else nullopt; the registration's prior_* fields say what it
  // did.
  std::optional<double> turntable_sigma_deg, turntable_tilt_sigma_deg;
  std::size_t constraints = 0;            // E_con terms added (all registered frames')
  fusion::deformation::SolveStats solve;
  // The last pose: how far the loop closure moved it (from the online deformation's estimate),
  // and how far from the tracked pose it ends.
  double moved_m = 0.0, moved_deg = 0.0;
  double correction_m = 0.0, correction_deg = 0.0;
  double ms = 0.0;                        // all of it, the registration included
};

// A frame's depth map and the decoder's confidence beside it, as add_frame() holds them. On a
// GPU a decoded frame's maps stay on the device (a 12-megapixel frame's are 96 MB); the depth
// map comes to the host only for what needs it there (the first frame's focus, a frame observer
// that asks): host_depth() downloads it the first time it is called; a keyframe's samples need
// only some of its rows (gathered_depth_rows).
struct FrameMaps {
  const Image32f* depth = nullptr;       // on the host once fetched; null: the frame has none
  const Image32f* confidence = nullptr;  // on the host; null: none there (a depth-map frame, a GPU decode)
  const Image32f* depth_on_device = nullptr;  // on a CUDA device (MemoryType::kDevice): the GPU copies, else null
  const Image32f* confidence_on_device = nullptr;
  std::function<void()> fetch;           // brings the depth map to the host; empty once done (or never needed)
  // Brings only these rows of it, one set after another (Image::gather_rows_from), and gives
  // where they landed (with fetch, or empty).
  std::function<const Image32f*(const std::vector<RowSet>&)> gather_rows;

  const Image32f* host_depth() {
    if (fetch) std::exchange(fetch, nullptr)();
    return depth;
  }
  // Only `rows` of the depth map on the host, one set after another, when it is on a GPU: a
  // keyframe's samples read ~2 % of a 12 MP map (the whole 48 MB came down for them, ~2 ms a
  // keyframe). Null when the map is on the host, or comes there whole: read host_depth().
  const Image32f* gathered_depth_rows(const std::vector<RowSet>& rows) {
    return fetch && gather_rows ? gather_rows(rows) : nullptr;
  }
  // Where the stages read them: the GPU's copies when there are, else the host's.
  const Image32f* depth_where_it_lives() const { return depth_on_device != nullptr ? depth_on_device : depth; }
  const Image32f* confidence_where_it_lives() const {
    return confidence_on_device != nullptr ? confidence_on_device : confidence;
  }
};

// Where ScanSession::final_surface() spent its time (ms, wall): the moving volume's part (the
// wait for a ship, the volume's own surface, the join), then the deformation of the whole model
// by the graph (0 without online deformation).
struct ModelTimes {
  fusion::FinalSurfaceTimes volume;
  double deform_ms = 0.0;
};

class ScanSession {
 public:
  // `patterns`: the set the frames' stacks use (null: frames carry depth maps). Validates and
  // allocates (decoder, volume buffers, tracker, raycaster) on options.device; throws
  // sls::Error naming the problem (kOutOfMemory when the volume does not fit).
  ScanSession(const ScannerCalibration& calibration, const PatternSet* patterns, const ScanSessionOptions& options);
  ~ScanSession();
  ScanSession(ScanSession&&) noexcept;
  ScanSession& operator=(ScanSession&&) noexcept;

  // Decodes, tracks and fuses one frame. A bad frame is reported (kSkipped / kLost), not
  // thrown; errors of the machine itself (GPU out of memory, a CUDA fault) still throw.
  FrameReport add_frame(const ScanFrame& frame);
  // Moves the next frame's pattern stack to the GPU ahead (a CUDA session with a pattern set;
  // otherwise nothing): called on another thread while add_frame() fuses the frame before, the
  // upload overlaps that frame's GPU work, and the add_frame() of `next` takes it
  // (Decoder::prefetch). `next`'s images must stay alive and unchanged until then. The one
  // call that may run beside add_frame(); returns whether it uploaded. A failed upload is not
  // thrown: the frame's own add_frame() uploads again and reports what is wrong.
  bool prefetch(const ScanFrame& next);
  bool uploads_ahead() const;  // whether prefetch() can do anything here

  const std::vector<FrameReport>& frames() const;
  std::vector<StampedPose> trajectory() const;  // fused frames, TUM stamps from timestamp_ns
  StageTimes totals() const;
  std::size_t fused_count() const;
  const fusion::VolumeGeometry& volume_geometry() const;  // the current volume's
  std::size_t volume_bytes() const;                       // both buffers of a moving volume
  std::size_t moves() const;
  // Revisited surface (RevisitPolicy): how far the scan has turned (degrees, as the policy
  // counts it), and the first frame from which the moving volume merges revisits (nullopt
  // while it ships every pass; with kMerge, the first fused frame).
  double turned_deg() const;
  std::optional<int> revisits_merged_from() const;

  // The model so far: the shipped parts plus the current volume's surface (world frame),
  // deformed by the graph when online deformation is on (each part by the nodes of its time;
  // the cloud then carries the float property "correction": how far each point moved, m).
  // `times`, when given: where the time went (ModelTimes).
  fusion::ExtractedSurface final_surface(ModelTimes* times = nullptr) const;
  // The same without the deformation (as tracked).
  fusion::ExtractedSurface final_surface_undeformed() const;
  // The fused frames' poses as tracked (trajectory() gives them deformed).
  std::vector<StampedPose> trajectory_undeformed() const;

  // The loop closure (paper section IV-C), triggered by the caller after the revolution: the
  // last loop_frames fused frames registered to the first frame's surface, each starting from
  // the deformed estimate of its pose (the turntable's angle with turntable_prior), then
  // loop_iterations Gauss–Newton steps with those constraints. Afterwards final_surface() and
  // trajectory() are the closed model. sls::Error(kInvalidArgument), the model kept as it
  // was: no frame fused ("before any frame"), online deformation off, too few keyframes, or
  // none of those frames registers to the first frame's surface (named, with the tracker's
  // reason; frames that do not register while others do are reported, not fatal).
  LoopClosureReport close_loop();
  const std::optional<LoopClosureReport>& loop_closure() const;
  // Online deformation: whether it runs, the worker's state (waits for it: drain), and what
  // it did per keyframe.
  bool deformation_enabled() const;
  DeformationStatus deformation_status(bool wait_for_worker) const;
  std::vector<KeyframeSolve> keyframe_solves() const;
  // The graph's size and CHOLMOD's work over the scan (after the worker is done).
  struct GraphSummary {
    std::size_t nodes = 0, links = 0, constraints = 0, analyses = 0, factorizations = 0;
    std::size_t rotation_priors = 0;  // frames' poses with the turntable's rotation prior
    double node_spacing_m = 0.0, region_radius_m = 0.0;
  };
  GraphSummary graph_summary() const;
  // Called at the end of every add_frame(), the frame already in frames(), with its report and
  // the depth map it was tracked and fused from (the decoded one for a pattern stack, the
  // frame's own for a depth map; none when the frame had none: skipped before decoding): on the
  // host through maps.host_depth() (a GPU decode's map comes down on that first ask only), and
  // on a CUDA device on the GPU, its content final. Valid during the call only: for front ends
  // that show each frame (the C API's frame report). Empty: none.
  using FrameObserver = std::function<void(const FrameReport& report, FrameMaps& maps)>;
  void set_frame_observer(FrameObserver observer);
  // A shaded raycast of the current volume from a pose (pictures).
  Image8u render(const Pose& T_world_camera) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The camera's motion (T_camera_before_camera_after) when the turntable turns by delta_deg
// about its calibrated axis: the object turns by delta, so in the object's frame the camera
// turns by -delta about the axis. The turntable prior's guess.
Pose turntable_camera_motion(const TurntableAxis& axis, double delta_deg);

}  // namespace sls::session
