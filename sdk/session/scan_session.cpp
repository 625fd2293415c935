#include "sdk/session/scan_session.h"
#include "sdk/session/scan_session_impl.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include <fmt/format.h>

#include "sdk/core/error.h"
#include "sdk/core/stopwatch.h"


namespace sls::session {
namespace {

using Clock = SteadyClock;

constexpr double kDegree = M_PI / 180.0;


// The texture of a pattern stack for the tracker's photometric term: white − black (the
// projector's light alone: no ambient, no camera black level, i.e. albedo × irradiance), or
// white − the black level when the set projects no black; false when it has no white.
bool stack_texture(const std::vector<Image16u>& images, const DecodeLayout& layout, double black_level_dn,
                   Image32f* texture) {
  if (layout.white_index < 0 || static_cast<std::size_t>(layout.white_index) >= images.size()) return false;
  const Image16u& white = images[static_cast<std::size_t>(layout.white_index)];
  const Image16u* black = layout.black_index >= 0 && static_cast<std::size_t>(layout.black_index) < images.size()
                              ? &images[static_cast<std::size_t>(layout.black_index)]
                              : nullptr;
  if (black != nullptr && (black->width() != white.width() || black->height() != white.height())) return false;
  *texture = Image32f(white.width(), white.height(), 0.0f);
  const float level = static_cast<float>(black_level_dn);
  for (std::size_t i = 0; i < white.pixel_count(); ++i) {
    texture->data()[i] =
        static_cast<float>(white.data()[i]) - (black != nullptr ? static_cast<float>(black->data()[i]) : level);
  }
  return true;
}

std::size_t count_valid(const Image32f& depth_m) {
  std::size_t count = 0;
  const float* data = depth_m.data();
  const auto pixels = static_cast<std::ptrdiff_t>(depth_m.pixel_count());
  // On all threads: a 12-megapixel map, every frame.
#if defined(_OPENMP)
#pragma omp parallel for schedule(static) reduction(+ : count)
#endif
  for (std::ptrdiff_t i = 0; i < pixels; ++i) count += data[i] > 0.0f && std::isfinite(data[i]);
  return count;
}

}  // namespace

double median_depth(const Image32f& depth_m) {
  std::vector<float> values;
  values.reserve(depth_m.pixel_count() / 4);
  for (int y = 0; y < depth_m.height(); ++y) {
    for (int x = 0; x < depth_m.width(); ++x) {
      const float z = depth_m(x, y);
      if (z > 0.0f && std::isfinite(z)) values.push_back(z);
    }
  }
  if (values.empty()) return 0.0;
  auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

Pose turntable_camera_motion(const TurntableAxis& axis, double delta_deg) {
  const Eigen::Matrix3d rotation =
      Eigen::AngleAxisd(-delta_deg * kDegree, axis.direction_camera.normalized()).toRotationMatrix();
  return Pose(rotation, axis.point_camera - rotation * axis.point_camera);
}

const char* frame_status_name(FrameStatus status) {
  switch (status) {
    case FrameStatus::kFused: return "fused";
    case FrameStatus::kLost: return "lost";
    case FrameStatus::kSkipped: return "skipped";
  }
  return "unknown";
}

StageTimes& StageTimes::operator+=(const StageTimes& other) {
  read_ms += other.read_ms;
  decode_ms += other.decode_ms;
  track_ms += other.track_ms;
  integrate_ms += other.integrate_ms;
  move_ms += other.move_ms;
  raycast_ms += other.raycast_ms;
  deform_ms += other.deform_ms;
  return *this;
}

double gpu_budget_voxels(const ScanSessionOptions& options, double held_bytes, double later_bytes) {
  if (!(options.max_gpu_bytes > 0.0) || !options.device.is_cuda()) return std::numeric_limits<double>::infinity();
  const double room = options.max_gpu_bytes - held_bytes - later_bytes;
  const double per_voxel =
      2.0 * static_cast<double>(fusion::bytes_per_voxel(options.voxel_format, options.integration.average_storage()));
  const auto needed = [&](double voxels) {
    return per_voxel * voxels +
           static_cast<double>(fusion::integration_gpu_bytes(options.integration, static_cast<std::size_t>(voxels)));
  };
  // The most voxels whose needs fit the room (both terms grow with the voxels): bisection.
  double low = 0.0, high = std::max(room, 0.0) / per_voxel;
  for (int i = 0; i < 64 && high - low > 1.0; ++i) {
    const double middle = 0.5 * (low + high);
    (needed(middle) <= room ? low : high) = middle;
  }
  return std::floor(low);
}

void ScanSessionOptions::validate() const {
  if (!fixed_volume) {
    if (!(volume_size_m.array() >= 0.0).all() || !volume_size_m.allFinite()) {
      throw_error(ErrorCode::kInvalidArgument, "scan volume size {} x {} x {} m (0 or positive)", volume_size_m.x(),
                  volume_size_m.y(), volume_size_m.z());
    }
    if (!(voxel_size_m >= 0.0) || !std::isfinite(voxel_size_m)) {
      throw_error(ErrorCode::kInvalidArgument, "scan voxel size {} m (0 or positive)", voxel_size_m);
    }
    if (!(max_voxels >= 8.0)) throw_error(ErrorCode::kInvalidArgument, "max_voxels {} (at least 8)", max_voxels);
    if (!(max_gpu_bytes >= 0.0) || !std::isfinite(max_gpu_bytes)) {
      throw_error(ErrorCode::kInvalidArgument, "GPU memory budget {} bytes (0: none, or positive)", max_gpu_bytes);
    }
    fusion::MovingVolumeOptions checked = moving;
    if (!(checked.focus_distance_m > 0.0)) checked.focus_distance_m = 0.1;  // filled from the first frame
    checked.validate();
  } else {
    fixed_volume->validate();
  }
  integration.validate(voxel_format);
  tracking.validate();
  deformation.validate();
  decode.validate();
}


ScanSession::ScanSession(const ScannerCalibration& calibration, const PatternSet* patterns,
                         const ScanSessionOptions& options) {
  options.validate();
  calibration.validate();
  // The prior turns the last pose about the calibrated axis: without an axis it would be
  // silently off while the caller believes it on.
  if (options.turntable_prior && !calibration.turntable) {
    throw_error(ErrorCode::kInvalidArgument,
                "the turntable prior needs the calibration's turntable axis, and this calibration has none "
                "(calibrate with board views on the turntable, or scan without the prior)");
  }
  require_device(options.device);
  impl_ = std::make_unique<Impl>(calibration, options);
  if (patterns != nullptr) {
    impl_->decoder.emplace(*patterns, calibration, options.device, options.decode, impl_->streams.frame,
                           impl_->streams.upload);
  }
  // A GPU decode's depth map comes down whole only where the host reads it all (the first frame's
  // focus, a frame observer that asks; keyframes take their rows alone); page-locked, it comes straight.
  if (options.device.is_cuda()) impl_->decoded.depth_m = Image32f(MemoryType::kPinned);
}

ScanSession::~ScanSession() = default;
ScanSession::ScanSession(ScanSession&&) noexcept = default;
ScanSession& ScanSession::operator=(ScanSession&&) noexcept = default;

bool ScanSession::prefetch(const ScanFrame& next) {
  Impl& s = *impl_;
  if (!s.decoder || next.pattern_images().empty() || !next.problem.empty()) return false;
  try {
    return s.decoder->prefetch(next.pattern_images());
  } catch (const Error&) {
    return false;  // add_frame(next) uploads it again and reports the problem as that frame's
  }
}

bool ScanSession::uploads_ahead() const { return impl_->decoder && impl_->options.device.is_cuda(); }

FrameReport ScanSession::add_frame(const ScanFrame& frame) {
  Impl& s = *impl_;
  FrameReport report;
  report.index = frame.index;
  report.timestamp_ns = frame.timestamp_ns;
  report.times.read_ms = frame.read_ms;
  FrameMaps maps;  // the frame's depth map and confidence, once decoded (or given)
  const auto finish = [&](FrameStatus status, std::string reason) -> FrameReport {
    report.status = status;
    report.reason = std::move(reason);
    s.totals += report.times;
    s.frames.push_back(report);
    if (s.frame_observer) s.frame_observer(s.frames.back(), maps);
    return report;
  };

  // Decode (or take the frame's depth map). A frame that cannot be decoded is skipped.
  if (!frame.problem.empty()) return finish(FrameStatus::kSkipped, frame.problem);
  const bool photometric = s.options.tracking.photometric_weight > 0.0;
  const CameraIntrinsics& camera = s.calibration.camera;
  if (photometric && frame.texture &&
      (frame.texture->width() != camera.width || frame.texture->height() != camera.height)) {
    return finish(FrameStatus::kSkipped,
                  fmt::format("texture of {}x{}, the camera has {}x{}", frame.texture->width(), frame.texture->height(),
                              camera.width, camera.height));
  }
  // On a GPU the decoded maps stay there (maps.fetch brings them down where the host needs them).
  const bool on_gpu = s.options.device.is_cuda();
  const std::vector<Image16u>& stack = frame.pattern_images();
  if (!stack.empty()) {
    if (!s.decoder) return finish(FrameStatus::kSkipped, "a pattern stack, but the session has no pattern set");
    const Clock::time_point start = Clock::now();
    try {
      s.decoder->decode(stack,
                        on_gpu ? DecodeOutputs::kDepthAndConfidenceOnDevice : DecodeOutputs::kDepthAndConfidence,
                        &s.decoded);
    } catch (const Error& error) {
      if (!is_frame_problem(error)) throw;
      report.times.decode_ms = ms_since(start);
      return finish(FrameStatus::kSkipped, fmt::format("cannot decode: {}", error.what()));
    }
    report.times.decode_ms = ms_since(start);
    maps.depth = &s.decoded.depth_m;
    maps.confidence = &s.decoded.confidence;
    maps.depth_on_device = s.decoder->depth_on_device();
    maps.confidence_on_device = s.decoder->confidence_on_device();
    if (on_gpu) {
      maps.confidence = nullptr;  // on the GPU only: nothing on the host reads it
      maps.fetch = [&s] { s.decoder->download_depth(&s.decoded.depth_m); };
      maps.gather_rows = [&s](const std::vector<RowSet>& rows) {
        // After the decode on the same stream.
        s.depth_rows.gather_rows_from(*s.decoder->depth_on_device(), rows, s.streams.frame);
        s.streams.frame.synchronize();
        return &s.depth_rows;
      };
    }
  } else if (frame.depth_m) {
    if (frame.depth_m->width() != s.calibration.camera.width ||
        frame.depth_m->height() != s.calibration.camera.height) {
      return finish(FrameStatus::kSkipped,
                    fmt::format("depth map of {}x{}, the camera has {}x{}", frame.depth_m->width(),
                                frame.depth_m->height(), s.calibration.camera.width, s.calibration.camera.height));
    }
    maps.depth = &*frame.depth_m;
    if (on_gpu) {
      // Uploaded once, then integrated and tracked on the GPU (counted with decoding).
      const Clock::time_point start = Clock::now();
      s.depth_upload.copy_from(*frame.depth_m, s.streams.frame);
      s.streams.frame.synchronize();
      maps.depth_on_device = &s.depth_upload;
      report.times.decode_ms = ms_since(start);
    }
  } else {
    return finish(FrameStatus::kSkipped, "neither a pattern stack nor a depth map");
  }
  // The valid pixels and, for a map on the GPU, the band it is integrated over: counted where
  // the map is (part of preparing it).
  std::optional<fusion::DepthMapSummary> summary_on_gpu;
  {
    const Clock::time_point start = Clock::now();
    if (maps.depth_on_device != nullptr) {
      summary_on_gpu = s.integrator.summarize(*maps.depth_on_device);
      report.depth_pixels = summary_on_gpu->valid_pixels;
    }
    if (!summary_on_gpu) report.depth_pixels = count_valid(*maps.depth);
    report.times.decode_ms += ms_since(start);
  }
  if (report.depth_pixels == 0) return finish(FrameStatus::kSkipped, "no valid depth in the frame");

  // The texture for the tracker's photometric term (with the depth map on the GPU, it is too).
  Image32f derived_texture;
  const Image32f* texture = nullptr;
  if (photometric) {
    const Clock::time_point start = Clock::now();  // part of preparing the frame
    if (frame.texture) {
      texture = &*frame.texture;
    } else if (!frame.pattern_images().empty() &&
               stack_texture(frame.pattern_images(), s.decoder->decode_params().layout, s.options.decode.black_level_dn,
                             &derived_texture)) {
      texture = &derived_texture;
    }
    if (texture != nullptr && maps.depth_on_device != nullptr) {
      // Once for tracking and a reference frame alike; `texture` may be a local of this scope.
      s.texture_on_device.copy_from(*texture, s.streams.frame);
      s.streams.frame.synchronize();
      texture = &s.texture_on_device;
    }
    report.times.decode_ms += ms_since(start);
  }

  // Track against the model, or take the known pose.
  Pose T_world_camera;
  if (frame.known_T_world_camera) {
    T_world_camera = *frame.known_T_world_camera;
  } else if (!s.have_model) {
    T_world_camera = s.last ? s.last->T_world_camera : Pose::identity();
  } else {
    const Pose guess = s.predict(frame);
    const Clock::time_point start = Clock::now();
    fusion::TrackingResult tracked;
    // With the turntable prior and the table's repeatability known, the table's motion since
    // the last fused frame is also a prior on the registration's rotation (fusion/pose_prior.h),
    // weighed against the surface; without its σ, the turntable's pose is the start only.
    fusion::PosePrior prior;
    if (s.turntable_guess(frame)) {
      if (const std::optional<fusion::PosePrior> p = s.turntable_pose_prior(s.last->T_world_camera, guess)) prior = *p;
    }
    // The volume the model was raycast from (it moves only after tracking).
    const fusion::VolumeGeometry model_volume = s.moving->volume().geometry();
    tracked = s.tracker.track(*maps.depth_where_it_lives(), s.model, s.T_world_model, guess, texture,
                              maps.confidence_where_it_lives(), &prior, &model_volume);
    report.times.track_ms = ms_since(start);
    if (!tracked.lost && s.options.verify_with_turntable) {
      // A registration that converged may still be wrong: the turntable says how far it turned.
      if (const auto check = s.turntable_disagreement_deg(frame, tracked.T_world_camera)) {
        const auto [off_deg, step_deg] = *check;
        const double allowed_deg = std::clamp(0.25 * std::abs(step_deg), 0.1, 2.0);
        if (off_deg > allowed_deg) {
          tracked.lost = true;
          tracked.reason = fmt::format(
              "the tracked motion disagrees with the turntable by {:.3f} deg (the turntable turned {:.3f} deg, at "
              "most {:.3f} deg allowed): tracking slid along a symmetry or locked onto the wrong surface{}",
              off_deg, step_deg, allowed_deg, s.options.turntable_prior ? "" : "; try --turntable-prior");
        }
      }
    }
    report.tracking = tracked;
    if (tracked.lost && tracked.too_little_overlap && s.turntable_guess(frame)) {
      // Too little overlap to verify, and a turntable to trust: fused at its pose and flagged,
      // so the model reaches the next views and the scan goes on.
      T_world_camera = guess;
      report.unverified = true;
      report.reason = fmt::format("fused at the turntable prior, unverified: {}", tracked.reason);
    } else if (tracked.lost) {
      report.T_world_camera = guess;
      return finish(FrameStatus::kLost, tracked.reason);
    } else {
      T_world_camera = tracked.T_world_camera;
    }
  }
  report.T_world_camera = T_world_camera;
  // A frame fused without tracking is the photometric term's next reference (the tracker
  // keeps a tracked one itself).
  if (texture != nullptr && (!report.tracking || report.unverified)) {
    const Clock::time_point start = Clock::now();  // the reference's pyramid: tracking work
    s.tracker.set_reference_frame(*maps.depth_where_it_lives(), *texture, T_world_camera);
    report.times.track_ms += ms_since(start);
  }

  // Move the volume when the camera has left it (before integrating, so the frame's whole view
  // goes into a volume placed for it), integrate, raycast the model for the next frame.
  s.place_volume(T_world_camera, maps);
  if (!s.first) s.first = Impl::Fused{frame.index, T_world_camera, frame.turntable_angle_deg};
  Clock::time_point start = Clock::now();
  if (s.moving) {
    // The loop closure's reference: the first frames as seen from the first pose, before the
    // volume leaves them.
    if (s.deformation && !s.reference_taken && s.moving->needs_move(T_world_camera)) {
      s.capture_reference(s.moving->volume());
      report.times.deform_ms += ms_since(start);
      start = Clock::now();
    }
    if (s.moving->needs_move(T_world_camera)) {
      report.shipped = s.collect_ship();  // the last move's, when it ships in the background still
      const std::size_t shipped_before = s.moving->shipped_cloud().size();
      report.move = s.moving->move_to(s.moving->placement(T_world_camera));
      report.times.move_ms = ms_since(start);
      if (report.move.shipping) {
        s.pending_ship = Impl::PendingShip{frame.index - 1, shipped_before, s.graph_grows()};
      } else if (s.deformation) {
        start = Clock::now();
        s.record_shipped(frame.index - 1, shipped_before, s.graph_grows());
        report.times.deform_ms += ms_since(start);
      }
    }
  }
  fusion::Volume& volume = *s.volume();  // the moved volume, if it moved
  start = Clock::now();
  // The map where it is: on the GPU (decoded there, or uploaded once) with the band summarised
  // there, else on the host.
  if (summary_on_gpu) {
    report.integration =
        s.integrator.integrate(volume, *maps.depth_on_device, s.calibration.camera, T_world_camera,
                               fusion::DepthBand{summary_on_gpu->near_m, summary_on_gpu->far_m});
  } else {
    report.integration = s.integrator.integrate(volume, *maps.depth, s.calibration.camera, T_world_camera);
  }
  report.times.integrate_ms = ms_since(start);
  if (!frame.known_T_world_camera) {
    start = Clock::now();
    // Guided by the depth just integrated from this pose: rays search only near it.
    s.raycaster.raycast(volume, T_world_camera, s.model, maps.depth_where_it_lives());
    s.raycaster.synchronize();  // for the stage's time; the next frame's tracking reads it in order
    report.times.raycast_ms = ms_since(start);
    s.T_world_model = T_world_camera;
    s.have_model = true;
  }
  if (s.deformation) {
    if (s.pending_ship && s.deformation->wants_keyframe(T_world_camera, s.focus_point(T_world_camera))) {
      if (s.ship_matchable_by_next_keyframe()) {
        start = Clock::now();
        report.shipped = s.collect_ship();  // before the keyframe, as if shipped by the move
        report.times.move_ms += ms_since(start);
      } else {
        ++s.pending_ship->keyframes;  // queued ahead of the part: the same result, no wait
      }
    }
    start = Clock::now();
    report.deformation = s.feed_deformation(frame.index, T_world_camera, frame.turntable_angle_deg, maps);
    report.times.deform_ms += ms_since(start);
  }
  start = Clock::now();
  s.count_turn(frame.index, T_world_camera, frame.turntable_angle_deg);
  report.times.move_ms += ms_since(start);
  s.before_last = s.last;
  s.last = Impl::Fused{frame.index, T_world_camera, frame.turntable_angle_deg};
  return finish(FrameStatus::kFused, report.reason);  // empty unless fused unverified
}

void ScanSession::Impl::count_turn(int frame, const Pose& T_world_camera, std::optional<double> angle_deg) {
  if (last) rotation_travelled_deg += (last->T_world_camera.inverse() * T_world_camera).angle_rad() / kDegree;
  turned_deg = first && first->angle_deg && angle_deg ? std::abs(*angle_deg - *first->angle_deg)
                                                      : rotation_travelled_deg;
  if (!moving) return;
  if (!revisits_merged_from && moving->merging_revisits()) revisits_merged_from = frame;  // kMerge, or set by hand
  if (options.revisits == RevisitPolicy::kAfterFirstRevolution && !revisits_merged_from && past_first_revolution()) {
    moving->start_merging_revisits();
    revisits_merged_from = frame;
  }
}

const char* revisit_policy_name(RevisitPolicy policy) {
  switch (policy) {
    case RevisitPolicy::kKeep: return "keep";
    case RevisitPolicy::kMerge: return "merge";
    case RevisitPolicy::kAfterFirstRevolution: return "auto";
  }
  return "?";
}

RevisitPolicy parse_revisit_policy(const std::string& name) {
  for (const RevisitPolicy policy : {RevisitPolicy::kKeep, RevisitPolicy::kMerge, RevisitPolicy::kAfterFirstRevolution}) {
    if (name == revisit_policy_name(policy)) return policy;
  }
  throw_error(ErrorCode::kInvalidArgument, "revisits \"{}\" (auto, keep or merge)", name);
}

double ScanSession::turned_deg() const { return impl_->turned_deg; }
std::optional<int> ScanSession::revisits_merged_from() const { return impl_->revisits_merged_from; }

const std::vector<FrameReport>& ScanSession::frames() const { return impl_->frames; }

void ScanSession::set_frame_observer(FrameObserver observer) { impl_->frame_observer = std::move(observer); }

StageTimes ScanSession::totals() const { return impl_->totals; }

std::size_t ScanSession::fused_count() const {
  return static_cast<std::size_t>(std::count_if(impl_->frames.begin(), impl_->frames.end(), [](const FrameReport& f) {
    return f.status == FrameStatus::kFused;
  }));
}

const fusion::VolumeGeometry& ScanSession::volume_geometry() const {
  const fusion::Volume* volume = std::as_const(*impl_).volume();  // const: a surface being prepared stays
  if (volume == nullptr) throw_error(ErrorCode::kInvalidArgument, "the scan has no volume yet: no frame was fused");
  return volume->geometry();
}

std::size_t ScanSession::volume_bytes() const {
  const fusion::Volume* volume = std::as_const(*impl_).volume();
  if (volume == nullptr) return 0;
  return impl_->moving ? 2 * volume->bytes() : volume->bytes();
}

std::size_t ScanSession::moves() const { return impl_->moving ? impl_->moving->moves() : 0; }

Image8u ScanSession::render(const Pose& T_world_camera) const {
  const fusion::Volume* volume = std::as_const(*impl_).volume();
  if (volume == nullptr) throw_error(ErrorCode::kInvalidArgument, "nothing to render: no frame was fused");
  // Its own raycaster: the session's holds the tracker's model on the GPU.
  fusion::Raycaster raycaster(impl_->options.device, impl_->calibration.camera, Impl::raycast_options(impl_->options),
                              impl_->streams.frame);
  return raycaster.raycast(*volume, T_world_camera).shaded;
}

}  // namespace sls::session
