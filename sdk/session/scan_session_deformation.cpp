// The scan session's online deformation (scan_session.h, scan_deformation.h): what the frame
// loop hands the graph's worker, the deformed model and trajectory, and the loop closure.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "fusion/deformation/map_deformation.h"
#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"
#include "sdk/core/stopwatch.h"
#include "sdk/session/scan_session.h"
#include "sdk/session/scan_session_impl.h"


namespace sls::session {
namespace {

using Clock = SteadyClock;

constexpr double kDegPerRad = 180.0 / M_PI;

// A sample whose 2-pixel neighbours lie further than this along the surface is on a depth
// edge: a hundred pixel footprints at the focus distance.
double edge_step_m(const CameraIntrinsics& camera, double focus_m) { return 100.0 * focus_m / camera.fx; }

void pose_difference(const Pose& a, const Pose& b, double* metres, double* degrees) {
  const Pose delta = a.inverse() * b;
  *metres = (b.translation() - a.translation()).norm();
  *degrees = delta.angle_rad() * kDegPerRad;
}

}  // namespace

void ScanSession::Impl::capture_reference(const fusion::Volume& volume) {
  if (reference_taken || !first) return;
  reference_volume = volume.geometry();
  raycaster.raycast(volume, first->T_world_camera, reference_model);
  raycaster.synchronize();
  reference_taken = true;
}

std::optional<fusion::MoveStats> ScanSession::Impl::collect_ship() {
  if (!moving || !moving->shipping()) return std::nullopt;
  const fusion::MoveStats stats = moving->finish_shipping();
  if (pending_ship) {
    if (deformation) record_shipped(pending_ship->time, pending_ship->shipped_before, pending_ship->graph_grows);
    pending_ship.reset();
  }
  return stats;
}

bool ScanSession::Impl::ship_matchable_by_next_keyframe() const {
  // The part's samples bind to nodes among the temporal_window made up to its time
  // (DeformationGraph::bind_before), the newest of which is the last node before the move: so
  // each sample's newest node is at least (nodes at the move) - temporal_window, and the
  // keyframe that makes node (nodes at the move) + keyframes matches only parts whose newest
  // node is revisit_gap_nodes older than its own.
  return pending_ship->keyframes + options.deformation.graph.temporal_window >= options.deformation.revisit_gap_nodes;
}

bool ScanSession::Impl::graph_grows() const {
  // Past the graph's revolution no keyframe comes to match them (first_revolution_only).
  return !(options.deformation.first_revolution_only && past_first_revolution());
}

void ScanSession::Impl::record_shipped(int time, std::size_t shipped_before, bool graph_grows) {
  const PointCloud& shipped = moving->shipped_cloud();
  parts.push_back({time, shipped.size(), moving->shipped_mesh().vertices.size()});
  if (deformation && graph_grows && shipped.size() > shipped_before) {
    deformation->add_shipped(time, shipped, shipped_before, shipped.size());
  }
}

void ScanSession::Impl::keep_loop_frame(int frame, const Pose& T_world_camera, std::optional<double> angle_deg,
                                        FrameMaps& maps) {
  const std::size_t slots = static_cast<std::size_t>(options.deformation.loop_frames);
  if (loop_frames.size() != slots) loop_frames.resize(slots);
  LoopFrame& slot = loop_frames[loop_frames_next];
  loop_frames_next = (loop_frames_next + 1) % slots;
  slot.index = frame;
  slot.T_world_camera = T_world_camera;
  slot.angle_deg = angle_deg;
  // Copies where the maps are, into the slot's memory when it already lives there.
  const auto keep = [this](const Image32f& source, Image32f& copy) {
    if (copy.memory_requested() != source.memory_type()) copy = Image32f(source.memory_type());
    copy.copy_from(source, streams.frame);
  };
  keep(*maps.depth_where_it_lives(), slot.depth);
  if (const Image32f* confidence = maps.confidence_where_it_lives()) {
    keep(*confidence, slot.confidence);
  } else {
    slot.confidence = Image32f();
  }
  streams.frame.synchronize();
}

std::optional<fusion::deformation::RotationPrior> ScanSession::Impl::turntable_rotation_prior(
    const Pose& T_world_camera, std::optional<double> angle_deg) const {
  if (!options.deformation.turntable_rotation_priors || !first || !first->angle_deg || !angle_deg ||
      !calibration.turntable) {
    return std::nullopt;
  }
  // Where the table puts this camera in the first frame's world: its angle since the first
  // frame, to the σ of two of its angles (turntable_pose_prior), with no drift however far it
  // turned.
  const Pose expected =
      first->T_world_camera * turntable_camera_motion(*calibration.turntable, *angle_deg - *first->angle_deg);
  const std::optional<fusion::PosePrior> prior = turntable_pose_prior(first->T_world_camera, expected);
  if (!prior) return std::nullopt;
  fusion::deformation::RotationPrior out;
  out.rotation = expected.rotation() * T_world_camera.rotation().transpose();
  // Across the axis no surer than about it: a table without wobble (σ_tilt 0, taken as 1e-6°)
  // would put an information 10¹⁴ times the rest of the system's into the graph's normal
  // equations, for no gain (the demo screw's result is the same to the last digit either way).
  fusion::PosePrior bounded = *prior;
  if (prior->sigma_rad < fusion::PosePrior::kNone) {
    bounded.tilt_sigma_rad = std::max(prior->tilt_sigma_rad, prior->sigma_rad);
  }
  out.information = bounded.information();
  return out;
}

FrameDeformation ScanSession::Impl::feed_deformation(int frame, const Pose& T_world_camera,
                                                     std::optional<double> angle_deg, FrameMaps& maps) {
  FrameDeformation out;
  keep_loop_frame(frame, T_world_camera, angle_deg, maps);
  // Past the graph's revolution (first_revolution_only) the frame adds nothing to it.
  if (!(options.deformation.first_revolution_only && past_first_revolution())) {
    add_to_graph(frame, T_world_camera, angle_deg, maps, &out);
  }
  const DeformationStatus status = deformation->status();
  out.nodes = status.nodes;
  out.constraints = status.constraints;
  out.pending = status.pending;
  out.solve_ms = status.last_solve_ms;
  return out;
}

void ScanSession::Impl::add_to_graph(int frame, const Pose& T_world_camera, std::optional<double> angle_deg,
                                     FrameMaps& maps, FrameDeformation* out) {
  const Eigen::Vector3d focus = focus_point(T_world_camera);
  std::optional<fusion::deformation::RotationPrior> prior = turntable_rotation_prior(T_world_camera, angle_deg);
  if (deformation->wants_keyframe(T_world_camera, focus)) {
    out->keyframe = true;
    // Only the rows the samples read come down from a GPU.
    const DepthMapSampler& sampler = keyframe_sampler();
    const double max_step_m = edge_step_m(calibration.camera, focus_distance_m);
    const Image32f* rows = maps.gathered_depth_rows(sampler.rows());
    deformation->add_keyframe(frame, T_world_camera, focus,
                              rows != nullptr ? sampler.sample_gathered(*rows, max_step_m)
                                              : sampler.sample(*maps.host_depth(), max_step_m),
                              std::move(prior));
  } else if (prior) {
    // Every frame's angle, not the keyframes' alone: each is off by the table's σ on its own,
    // and the more of them a node's blend weighs, the less of that is left.
    deformation->add_rotation_prior(frame, focus, *prior);
  }
}

fusion::ExtractedSurface ScanSession::Impl::surface(bool deformed, ModelTimes* times) const {
  if (fixed) return fusion::extract_surface(fixed->to_host());
  if (!moving) return {};
  fusion::FinalSurfaceTimes* const volume_times = times != nullptr ? &times->volume : nullptr;
  if (!deformed || !deformation || !last) return moving->final_surface(volume_times);
  deformation->drain();
  const fusion::deformation::DeformationGraph& graph = deformation->graph();
  if (graph.size() == 0) return moving->final_surface(volume_times);
  // Deformed as it is joined: the shipped parts' and the volume's points are read where they
  // are and written, moved, into the model once (a copy and then a pass in place cost 0.45 s
  // more at the paper's size).
  const fusion::MovingVolume::SurfaceParts pieces = moving->final_surface_parts(volume_times);
  SteadyClock::time_point start = SteadyClock::now();
  fusion::ExtractedSurface result;
  result.cloud = join_clouds(*pieces.shipped_cloud, pieces.live.cloud, false);
  result.mesh = join_meshes(*pieces.shipped_mesh, pieces.live.mesh, false);
  if (volume_times != nullptr) volume_times->join_ms = ms_since(start);
  start = SteadyClock::now();
  const std::vector<fusion::deformation::NodeTransform> transforms = graph.transforms();
  // The model's parts, each observed up to its own frame: its points [cloud_begin, cloud_end)
  // (and its mesh's vertices likewise), read from `cloud` and `vertices` from `cloud_from` and
  // `mesh_from` on.
  struct Part {
    int time = 0;
    const PointCloud* cloud = nullptr;
    std::size_t cloud_from = 0, cloud_begin = 0, cloud_end = 0;
    const PointCloud* vertices = nullptr;
    std::size_t mesh_from = 0, mesh_begin = 0, mesh_end = 0;
  };
  std::vector<Part> model_parts;
  const PointCloud& shipped_cloud = *pieces.shipped_cloud;
  const PointCloud& shipped_vertices = pieces.shipped_mesh->vertices;
  std::size_t cloud_begin = 0, mesh_begin = 0;
  const auto add_part = [&](int time, const PointCloud& cloud, std::size_t cloud_from, std::size_t cloud_end,
                            const PointCloud& vertices, std::size_t mesh_from, std::size_t mesh_end) {
    model_parts.push_back(
        {time, &cloud, cloud_from, cloud_begin, cloud_end, &vertices, mesh_from, mesh_begin, mesh_end});
    cloud_begin = cloud_end;
    mesh_begin = mesh_end;
  };
  for (const ShippedPart& part : parts) {
    add_part(part.time, shipped_cloud, cloud_begin, part.cloud_end, shipped_vertices, mesh_begin, part.mesh_vertex_end);
  }
  // Shipped surface no part records (none, unless a ship came after the last record) goes with
  // the volume's own surface, at the last frame's nodes.
  add_part(last->index, shipped_cloud, cloud_begin, shipped_cloud.size(), shipped_vertices, mesh_begin,
           shipped_vertices.size());
  add_part(last->index, pieces.live.cloud, 0, result.cloud.size(), pieces.live.mesh.vertices, 0,
           result.mesh.vertices.size());
  // Each vertex that is one of its part's points takes that point's deformed values (the same
  // bits): the mesh has about as many vertices as the cloud has points, and deforming them took
  // about half of the deformation's time (0.51-0.54 -> 0.29-0.31 s at the paper's size, H200).
  // The parts' ranges checked first: the matches run on threads, where an error cannot be thrown.
  for (const Part& part : model_parts) {
    if (part.cloud_end < part.cloud_begin || part.mesh_end < part.mesh_begin ||
        part.cloud_end > result.cloud.size() || part.mesh_end > result.mesh.vertices.size() ||
        part.cloud_from + (part.cloud_end - part.cloud_begin) > part.cloud->size() ||
        part.mesh_from + (part.mesh_end - part.mesh_begin) > part.vertices->size()) {
      throw_error(ErrorCode::kInternal,
                  "map deformation: a part's points [{}, {}) or vertices [{}, {}) lie outside the model",
                  part.cloud_begin, part.cloud_end, part.mesh_begin, part.mesh_end);
    }
  }
  std::vector<std::int64_t> same_point;
  resize_populated(&same_point, result.mesh.vertices.size());
#if defined(_OPENMP)
#pragma omp parallel for schedule(dynamic, 1)
#endif
  for (std::ptrdiff_t p = 0; p < static_cast<std::ptrdiff_t>(model_parts.size()); ++p) {
    const Part& part = model_parts[static_cast<std::size_t>(p)];
    fusion::deformation::match_vertices_to_points(
        *part.vertices, part.mesh_from, part.mesh_from + (part.mesh_end - part.mesh_begin), *part.cloud,
        part.cloud_from, part.cloud_from + (part.cloud_end - part.cloud_begin), part.cloud_begin,
        same_point.data() + part.mesh_begin);
  }
  std::vector<float> moved;
  for (const Part& part : model_parts) {
    fusion::deformation::deform_cloud_part(graph, transforms, part.time, *part.cloud, part.cloud_from,
                                           part.cloud_from + (part.cloud_end - part.cloud_begin), &result.cloud,
                                           part.cloud_begin, &moved);
    fusion::deformation::deform_vertices_part(graph, transforms, part.time, *part.vertices, part.mesh_from,
                                              part.mesh_from + (part.mesh_end - part.mesh_begin), &result.mesh.vertices,
                                              part.mesh_begin, same_point.data() + part.mesh_begin, result.cloud);
  }
  result.cloud.properties.push_back({"correction", std::move(moved)});
  if (times != nullptr) times->deform_ms = ms_since(start);
  return result;
}

// A part shipping in the background is recorded first: the deformation binds it to its time.
fusion::ExtractedSurface ScanSession::final_surface(ModelTimes* times) const {
  impl_->collect_ship();
  return impl_->surface(true, times);
}
fusion::ExtractedSurface ScanSession::final_surface_undeformed() const {
  impl_->collect_ship();
  return impl_->surface(false);
}

std::vector<StampedPose> ScanSession::trajectory_undeformed() const {
  std::vector<StampedPose> poses;
  for (const FrameReport& frame : impl_->frames) {
    if (frame.status != FrameStatus::kFused) continue;
    poses.push_back({static_cast<double>(frame.timestamp_ns) * 1e-9, frame.T_world_camera});
  }
  return poses;
}

std::vector<StampedPose> ScanSession::trajectory() const {
  const Impl& s = *impl_;
  std::vector<StampedPose> poses = trajectory_undeformed();
  if (!s.deformation) return poses;
  s.deformation->drain();
  std::size_t i = 0;
  for (const FrameReport& frame : s.frames) {
    if (frame.status != FrameStatus::kFused) continue;
    StampedPose& pose = poses[i++];
    pose.T_world_camera = s.deformation->deform_pose(frame.index, pose.T_world_camera, s.focus_point(pose.T_world_camera));
  }
  return poses;
}

bool ScanSession::deformation_enabled() const { return impl_->deformation != nullptr; }

DeformationStatus ScanSession::deformation_status(bool wait_for_worker) const {
  if (!impl_->deformation) return {};
  if (wait_for_worker) impl_->deformation->drain();
  return impl_->deformation->status();
}

std::vector<KeyframeSolve> ScanSession::keyframe_solves() const {
  if (!impl_->deformation) return {};
  return impl_->deformation->keyframe_solves();
}

ScanSession::GraphSummary ScanSession::graph_summary() const {
  GraphSummary summary;
  if (!impl_->deformation) return summary;
  impl_->deformation->drain();
  const fusion::deformation::DeformationGraph& graph = impl_->deformation->graph();
  summary.nodes = graph.size();
  summary.links = graph.edges().size();
  summary.constraints = graph.constraints().size();
  summary.rotation_priors = graph.rotation_priors();
  summary.analyses = graph.analyses();
  summary.factorizations = graph.factorizations();
  summary.node_spacing_m = graph.options().length_scale_m;
  summary.region_radius_m = graph.options().region_radius_m;
  return summary;
}

const std::optional<LoopClosureReport>& ScanSession::loop_closure() const { return impl_->loop; }

LoopClosureReport ScanSession::close_loop() {
  Impl& s = *impl_;
  const Clock::time_point start = Clock::now();
  if (!s.last || !s.first) {
    throw_error(ErrorCode::kInvalidArgument, "loop closure asked before any frame was fused");
  }
  if (!s.deformation) {
    throw_error(ErrorCode::kInvalidArgument,
                "loop closure needs online deformation, which is off for this scan ({})",
                s.options.fixed_volume ? "a fixed volume with known poses" : "turned off in its options");
  }
  if (s.last->index == s.first->index) {
    throw_error(ErrorCode::kInvalidArgument, "loop closure needs more than one fused frame (only frame {})",
                s.first->index);
  }
  // The model's surface still in the volume is found beside the registrations and the solve,
  // which do not change the volume (as ships are, where they are: on a GPU).
  if (s.moving && s.moving->options().ship_in_background) s.moving->prepare_final_surface();
  s.collect_ship();
  s.deformation->drain();
  fusion::deformation::DeformationGraph& graph = s.deformation->graph();
  if (static_cast<int>(graph.size()) <= graph.pinned_count()) {
    throw_error(ErrorCode::kInvalidArgument,
                "loop closure: too few keyframes ({} graph nodes, the first {} pinned): the scan moved too little "
                "for a loop",
                graph.size(), graph.pinned_count());
  }
  if (!s.reference_taken) s.capture_reference(std::as_const(*s.moving).volume());  // the volume never moved

  // Register the kept last frames (newest first) to the first frame's surface, each from the
  // best guess of its pose in the first frame's world: the turntable's angle when it is known
  // and used, else the online deformation's estimate. Several frames, because one
  // registration's error is what is left of the loop (measured: docs/benchmarks.md).
  const Impl::Fused& last = *s.last;
  const Impl::Fused& first = *s.first;
  const Pose deformed_last = s.deformation->deform_pose(last.index, last.T_world_camera, s.focus_point(last.T_world_camera));
  std::vector<const Impl::LoopFrame*> kept;
  for (const Impl::LoopFrame& frame : s.loop_frames) {
    if (frame.index > first.index) kept.push_back(&frame);
  }
  std::sort(kept.begin(), kept.end(), [](const Impl::LoopFrame* a, const Impl::LoopFrame* b) { return a->index > b->index; });
  LoopClosureReport report;
  report.first_frame = first.index;
  report.last_frame = last.index;
  struct Registered {
    const Impl::LoopFrame* frame;
    Pose T_world_camera;
    double residual_rms_m;
    Image32f depth;
  };
  std::vector<Registered> registered;
  for (const Impl::LoopFrame* frame : kept) {
    Pose guess = s.deformation->deform_pose(frame->index, frame->T_world_camera, s.focus_point(frame->T_world_camera));
    fusion::PosePrior prior;  // none unless the turntable's angles and their σ are known
    if (s.options.turntable_prior && s.calibration.turntable && frame->angle_deg && first.angle_deg) {
      guess = first.T_world_camera *
              turntable_camera_motion(*s.calibration.turntable, *frame->angle_deg - *first.angle_deg);
      // With the table's repeatability known, its motion is a prior on the registration's
      // rotation (about the axis and across it) rather than only a start.
      if (const std::optional<fusion::PosePrior> p = s.turntable_pose_prior(first.T_world_camera, guess)) {
        prior = *p;
        report.turntable_sigma_deg = s.calibration.turntable->angle_sigma_deg;
        report.turntable_tilt_sigma_deg = s.calibration.turntable->tilt_sigma_deg;
      }
    }
    const fusion::TrackingResult registration =
        s.tracker.track(frame->depth, s.reference_model, first.T_world_camera, guess, nullptr,
                        frame->confidence.empty() ? nullptr : &frame->confidence, &prior, &s.reference_volume);
    Image32f depth = frame->depth.copy_to(MemoryType::kHost);
    if (registration.lost) {
      report.unregistered.push_back({frame->index, registration.reason});
      continue;
    }
    if (registered.empty()) pose_difference(guess, registration.T_world_camera, &report.guess_moved_m, &report.guess_moved_deg);
    if (registered.empty()) report.registration = registration;  // the newest one that registers
    registered.push_back({frame, registration.T_world_camera, registration.residual_rms_m, std::move(depth)});
  }
  if (registered.empty()) {
    const std::pair<int, std::string>& newest = report.unregistered.front();
    throw_error(ErrorCode::kInvalidArgument,
                "loop closure: the last fused frame ({}) does not register to the first frame's ({}) surface: {}{} "
                "(the scan is not a closed loop, or drifted beyond the tracker's reach); the model is kept as online "
                "deformation left it",
                newest.first, first.index, newest.second,
                kept.size() > 1 ? fmt::format(", nor do the {} kept frames before it", kept.size() - 1) : "");
  }

  // Their points: where tracking put them (deformed by the nodes of their time) should be
  // where the registration puts them. Each point is where one rigid registration puts it: as
  // certain as that registration's residual, not as a surface point's noise (σ_con).
  const double voxel_m = std::as_const(*s.moving).volume().geometry().voxel_size_m;
  for (const Registered& r : registered) {
    const SurfaceSamples samples =
        s.keyframe_sampler().sample(r.depth, edge_step_m(s.calibration.camera, s.focus_distance_m));
    const double sigma_registration = std::max(r.residual_rms_m, 0.1 * voxel_m);
    const double weight = std::pow(s.deformation->constraint_sigma_m() / sigma_registration, 2.0);
    for (const Eigen::Vector3f& p_camera : samples.points) {
      const Eigen::Vector3d p = p_camera.cast<double>();
      fusion::deformation::Constraint constraint;
      constraint.source = r.frame->T_world_camera * p;
      constraint.source_binding = graph.bind_before(constraint.source, r.frame->index);
      constraint.target = r.T_world_camera * p;
      constraint.weight = weight;
      graph.add_constraint(constraint);
    }
    report.constraints += samples.points.size();
    report.registered_frames.push_back(r.frame->index);
  }
  report.solve = graph.solve(s.options.deformation.loop_iterations);
  const Pose closed = s.deformation->deform_pose(last.index, last.T_world_camera, s.focus_point(last.T_world_camera));
  pose_difference(deformed_last, closed, &report.moved_m, &report.moved_deg);
  pose_difference(last.T_world_camera, closed, &report.correction_m, &report.correction_deg);
  report.ms = ms_since(start);
  s.loop = report;
  return report;
}

}  // namespace sls::session
