#include "fusion/moving_volume.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <future>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "fusion/extract_internal.h"
#include "fusion/extract_shared.h"
#include "fusion/moving_volume_gpu.h"
#include "fusion/resample_shared.h"
#include "fusion/revisit_filter.h"
#include "sdk/core/error.h"
#include "sdk/core/host_memory.h"
#include "sdk/core/serial_worker.h"
#include "sdk/core/stopwatch.h"

namespace sls::fusion {

void MovingVolumeOptions::validate() const {
  if (!(focus_distance_m > 0.0) || !std::isfinite(focus_distance_m)) {
    throw_error(ErrorCode::kInvalidArgument, "moving volume: focus distance {} m is not positive and finite",
                focus_distance_m);
  }
  if (!(margin_fraction >= 0.0 && margin_fraction < 0.5)) {
    throw_error(ErrorCode::kInvalidArgument, "moving volume: margin fraction {} outside [0, 0.5)", margin_fraction);
  }
  if (!(max_rotation_deg > 0.0) || !std::isfinite(max_rotation_deg)) {
    throw_error(ErrorCode::kInvalidArgument, "moving volume: max rotation {} deg is not positive and finite",
                max_rotation_deg);
  }
  detail::check_extract_options(extract);
}

namespace {

constexpr double kDegPerRad = 57.295779513082320876798;

// Appends b's points to a (the same per-point arrays; a cloud that is empty takes b's layout).
void append_cloud(PointCloud* a, const PointCloud& b) {
  if (b.empty()) return;
  if (a->empty()) {
    *a = b;
    return;
  }
  a->positions.insert(a->positions.end(), b.positions.begin(), b.positions.end());
  a->normals.insert(a->normals.end(), b.normals.begin(), b.normals.end());
  a->confidence.insert(a->confidence.end(), b.confidence.begin(), b.confidence.end());
  a->colors.insert(a->colors.end(), b.colors.begin(), b.colors.end());
  for (PointProperty& property : a->properties) {
    const PointProperty* more = b.find_property(property.name);
    if (more == nullptr) {
      throw_error(ErrorCode::kInternal, "moving volume: a surface part lacks the property '{}'", property.name);
    }
    property.values.insert(property.values.end(), more->values.begin(), more->values.end());
  }
}

void append_mesh(TriangleMesh* a, const TriangleMesh& b) {
  const auto offset = static_cast<std::int32_t>(a->vertices.size());
  append_cloud(&a->vertices, b.vertices);
  // No reserve to the exact size: that reallocates every time, and copying all faces shipped
  // so far on every move made a revolution's moves quadratic (~110 ms a move by the end at 960³).
  for (const auto& face : b.faces) a->faces.push_back({face[0] + offset, face[1] + offset, face[2] + offset});
}

// The old volume's grid coordinates of the new volume's (voxel centres at integers), both of
// voxel size h: g_old = R g_new + R (0.5, 0.5, 0.5) + t / h - (0.5, 0.5, 0.5), (R, t) = T_old_new.
Rigid3f grid_transform(const Pose& T_world_old, const Pose& T_world_new, double voxel_size_m) {
  const Pose T_old_new = T_world_old.inverse() * T_world_new;
  const Eigen::Matrix3d rotation = T_old_new.rotation();
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(0.5);
  const Eigen::Vector3d offset = rotation * half + T_old_new.translation() / voxel_size_m - half;
  Rigid3f grid;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) grid.rotation.m[r * 3 + c] = static_cast<float>(rotation(r, c));
  }
  grid.translation = Vec3f{static_cast<float>(offset.x()), static_cast<float>(offset.y()),
                           static_cast<float>(offset.z())};
  return grid;
}

void resample_cpu(const VolumeView& from, const VolumeView& to, const Rigid3f& grid_from_to) {
  std::fill(to.surface_bricks, to.surface_bricks + to.brick_count(), std::uint8_t{0});
#if defined(_OPENMP)
#pragma omp parallel for schedule(dynamic, 1)
#endif
  for (int k = 0; k < to.nz; ++k) {
    for (int j = 0; j < to.ny; ++j) {
      for (int i = 0; i < to.nx; ++i) resample_voxel(from, to, grid_from_to, i, j, k);
    }
  }
}

// Every moving volume's ships in the background, on one thread for the process: a thread per
// ship, or per volume, made an OpenMP team and malloc arenas each time, and a process scanning
// again and again grew by ~15 MiB a scan (docs/reliability.md, "long runs"). Volumes of
// concurrent scans take turns.
SerialWorker& ship_worker() {
  static SerialWorker worker;
  return worker;
}
}  // namespace

// The revisit filter's cells: two voxels, about the drift between two passes of a scan.
constexpr double kRevisitCellVoxels = 2.0;

struct MovingVolume::Impl {
  MovingVolumeOptions options;
  Device device;
  std::vector<Volume> buffers;  // the ping-pong pair
  int current = 0;
  PointCloud shipped_cloud;
  TriangleMesh shipped_mesh;
  std::optional<RevisitFilter> revisits;  // while merging
  bool merging = false;                   // options.merge_revisits, or start_merging_revisits()
  std::size_t moves = 0;
  // The session's or its own (CUDA): resampling follows the frames' work on `resample`;
  // shipping (and final_surface's extraction) runs beside it on `ship`.
  GpuStream resample_stream, ship_gpu_stream;
  std::unique_ptr<detail::MovingVolumeGpu> gpu;  // on a GPU: its buffers and launches
  // The ship in the background (options.ship_in_background): the job, and the move's stats,
  // whose ship figures the job fills, until finish_shipping() collects them.
  std::future<void> ship_job;
  MoveStats ship_stats;
  bool ship_pending = false;
  // The current volume's surface found beside the caller (prepare_final_surface()): the job,
  // and what it fills for final_surface_parts() to take.
  std::future<void> prepared_job;
  ExtractedSurface prepared_surface;
  FinalSurfaceTimes prepared_times;

  ~Impl() {
    // Both read the buffers, the GPU half and the streams.
    if (prepared_job.valid()) prepared_job.wait();
    if (ship_job.valid()) ship_job.wait();
  }
  // Waits for a ship in the background; rethrows what it threw.
  void wait_shipping() {
    if (ship_job.valid()) ship_job.get();
  }
  // Waits for a surface being prepared and drops it (what it threw too): the volume may change.
  void drop_prepared() {
    if (!prepared_job.valid()) return;
    prepared_job.wait();
    prepared_job = {};
    prepared_surface = ExtractedSurface{};
  }
  // Extracts the leaving region of `from`, filters revisits, appends to the shipped surface,
  // and fills `stats`' ship figures.
  void ship(const Volume& from, const OrientedRegion& leaving, MoveStats* stats) {
    const auto ship_start = SteadyClock::now();
    ExtractedSurface part = extract_part(from, leaving, &stats->ship_assemble_ms);
    if (merging) {
      if (!revisits) revisits.emplace(kRevisitCellVoxels * from.geometry().voxel_size_m);
      part = revisits->filter(part);
    }
    stats->shipped_points = part.cloud.size();
    stats->shipped_triangles = part.mesh.faces.size();
    append_cloud(&shipped_cloud, part.cloud);
    append_mesh(&shipped_mesh, part.mesh);
    stats->ship_ms = ms_since(ship_start);
  }

  Volume& now() { return buffers[static_cast<std::size_t>(current)]; }
  Volume& other() { return buffers[static_cast<std::size_t>(1 - current)]; }

  // The part of `volume`'s surface in `region`, extracted where the volume lives.
  // assemble_ms: of the time, what the host spent assembling (CUDA; 0 on the CPU,
  // where extraction and assembly are one pass).
  ExtractedSurface extract_part(const Volume& volume, const OrientedRegion& region, double* assemble_ms) {
    *assemble_ms = 0.0;
    if (!volume.device().is_cuda()) {
      return extract_surface(volume.view(), volume.geometry().T_world_volume, region, options.extract);
    }
    return gpu->extract_part(volume, region, options.extract, assemble_ms);
  }

  // The current volume's whole surface, where it lives: on a GPU as a move ships its surface
  // (the crossings and cells found there, only they downloaded, not the 4.4 GB of a 960^3
  // volume, assembled on the host), everything kept: the outside of an empty box (the same
  // surface as extract_surface's, in the same order:
  // MovingVolumeCuda.MovingEverythingOutShipsTheSameWholeSurface). Fills spent's extract_ms
  // and assemble_ms.
  ExtractedSurface whole_surface(FinalSurfaceTimes* spent) {
    const SteadyClock::time_point start = SteadyClock::now();
    const Volume& volume = buffers[static_cast<std::size_t>(current)];
    ExtractedSurface surface;
    if (volume.device().is_cuda()) {
      OrientedRegion everything;
      everything.T_world_box = volume.geometry().T_world_volume;
      everything.min = Eigen::Vector3d::Ones();
      everything.max = -Eigen::Vector3d::Ones();
      everything.keep_outside = true;
      surface = extract_part(volume, everything, &spent->assemble_ms);
    } else {
      surface = extract_surface(volume, options.extract);
    }
    spent->extract_ms = ms_since(start);
    return surface;
  }

  void resample(const Volume& from, Volume& to) {
    const Rigid3f grid = grid_transform(from.geometry().T_world_volume, to.geometry().T_world_volume,
                                        from.geometry().voxel_size_m);
    if (!device.is_cuda()) {
      resample_cpu(from.view(), to.view(), grid);
      return;
    }
    gpu->resample(from, to, grid);
  }
};

MovingVolume::MovingVolume(int nx, int ny, int nz, double voxel_size_m, VoxelFormat format, const Device& device,
                           const MovingVolumeOptions& options, AverageStorage average, const GpuStream& stream,
                           const GpuStream& ship_stream)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  impl_->options = options;
  impl_->merging = options.merge_revisits;
  impl_->device = device;
  VolumeGeometry geometry;
  geometry.nx = nx;
  geometry.ny = ny;
  geometry.nz = nz;
  geometry.voxel_size_m = voxel_size_m;
  impl_->buffers.reserve(2);
  if (!device.is_cuda()) {
    // Both buffers admitted together: the second must not be the one that does not fit.
    const std::size_t bytes = geometry.voxel_count() * bytes_per_voxel(format, average);
    admit_host_allocation(2 * bytes,
                          fmt::format("a moving volume of two {} x {} x {} buffers ({})", nx, ny, nz,
                                      voxel_format_name(format)),
                          "use fewer or larger voxels");
  }
  impl_->buffers.emplace_back(geometry, format, device, average);
  impl_->buffers.emplace_back(geometry, format, device, average);
  impl_->resample_stream = GpuStream::or_create(stream, device);
  impl_->ship_gpu_stream = GpuStream::or_create(ship_stream, device);
  if (device.is_cuda()) {
    impl_->gpu = std::make_unique<detail::MovingVolumeGpu>(device, impl_->resample_stream, impl_->ship_gpu_stream);
  }
}

MovingVolume::~MovingVolume() = default;
MovingVolume::MovingVolume(MovingVolume&&) noexcept = default;
MovingVolume& MovingVolume::operator=(MovingVolume&&) noexcept = default;

const MovingVolumeOptions& MovingVolume::options() const { return impl_->options; }

Pose MovingVolume::placement(const Pose& T_world_camera) const {
  const Eigen::Vector3d focus = T_world_camera * Eigen::Vector3d(0.0, 0.0, impl_->options.focus_distance_m);
  const Eigen::Vector3d half = 0.5 * impl_->buffers.front().geometry().size_m();
  return Pose(T_world_camera.quaternion(), focus - T_world_camera.rotation() * half);
}

void MovingVolume::place(const Pose& T_world_camera) {
  Impl& s = *impl_;
  s.drop_prepared();
  s.wait_shipping();
  s.ship_pending = false;
  s.now().clear();
  s.now().set_pose(placement(T_world_camera));
  s.shipped_cloud = PointCloud{};
  s.shipped_mesh = TriangleMesh{};
  s.revisits.reset();
  s.merging = s.options.merge_revisits;
  s.moves = 0;
}

void MovingVolume::start_merging_revisits() {
  Impl& s = *impl_;
  s.wait_shipping();
  if (s.merging) return;
  if (!s.revisits) s.revisits.emplace(kRevisitCellVoxels * s.now().geometry().voxel_size_m);
  s.revisits->remember(s.shipped_cloud);
  s.revisits->remember(s.shipped_mesh.vertices);
  s.merging = true;
}

bool MovingVolume::merging_revisits() const { return impl_->merging; }

Volume& MovingVolume::volume() {
  impl_->drop_prepared();
  return impl_->now();
}
const Volume& MovingVolume::volume() const { return impl_->buffers[static_cast<std::size_t>(impl_->current)]; }

MoveStats MovingVolume::follow(const Pose& T_world_camera) {
  if (!needs_move(T_world_camera)) return MoveStats{};
  return move_to(placement(T_world_camera));
}

bool MovingVolume::needs_move(const Pose& T_world_camera) const {
  const VolumeGeometry& geometry = volume().geometry();
  const Pose T_volume_world = geometry.T_world_volume.inverse();
  const Eigen::Vector3d focus =
      T_volume_world * (T_world_camera * Eigen::Vector3d(0.0, 0.0, impl_->options.focus_distance_m));
  const Eigen::Vector3d size = geometry.size_m();
  const double margin = impl_->options.margin_fraction;
  bool leaves = false;
  for (int axis = 0; axis < 3; ++axis) {
    leaves = leaves || focus[axis] < margin * size[axis] || focus[axis] > (1.0 - margin) * size[axis];
  }
  const double turned_deg =
      Pose(geometry.T_world_volume.quaternion().conjugate() * T_world_camera.quaternion(), Eigen::Vector3d::Zero())
          .angle_rad() *
      kDegPerRad;
  return leaves || turned_deg > impl_->options.max_rotation_deg;
}

MoveStats MovingVolume::move_to(const Pose& T_world_volume) {
  Impl& s = *impl_;
  // The last move's ship reads the buffer this one resamples into; a prepared surface, the
  // one it moves from.
  s.drop_prepared();
  s.wait_shipping();
  Volume& from = s.now();
  Volume& to = s.other();
  const VolumeGeometry& geometry = from.geometry();
  const Pose T_world_old = geometry.T_world_volume;
  MoveStats stats;
  stats.moved = true;
  const Eigen::Vector3d centre = 0.5 * geometry.size_m();
  stats.translation_m = (T_world_volume * centre - T_world_old * centre).norm();
  stats.rotation_deg =
      Pose(T_world_old.quaternion().conjugate() * T_world_volume.quaternion(), Eigen::Vector3d::Zero()).angle_rad() *
      kDegPerRad;
  to.set_pose(T_world_volume);

  // Ship what leaves: the old surface outside the new volume's sample box (the hull of its
  // voxel centres, where its own crossings and cells lie), so the two never overlap.
  OrientedRegion leaving;
  leaving.T_world_box = T_world_volume;
  const double h = geometry.voxel_size_m;
  leaving.min = Eigen::Vector3d::Constant(0.5 * h);
  leaving.max = geometry.size_m() - Eigen::Vector3d::Constant(0.5 * h);
  leaving.keep_outside = true;
  if (s.options.ship_in_background) {
    // `from` stays as it is until the next move, which waits for this ship first.
    stats.shipping = true;
    s.ship_stats = stats;
    s.ship_pending = true;
    Impl* impl = &s;
    const Volume* leaving_volume = &from;
    s.ship_job = ship_worker().submit([impl, leaving_volume, leaving] {
      require_device(impl->device);  // the worker thread's current device
      // The host's assembly on every core: with the pattern stacks captured page-locked the
      // frame loop stages nothing on the host, and at the paper's size the assembly took 40 ms
      // on 16 cores against 110 ms on the quarter it was held to while staging competed
      // (docs/benchmarks.md, 2026-11-29 night).
      impl->ship(*leaving_volume, leaving, &impl->ship_stats);
    });
  } else {
    s.ship(from, leaving, &stats);
  }

  const auto resample_start = SteadyClock::now();
  s.resample(from, to);
  stats.resample_ms = ms_since(resample_start);
  s.current = 1 - s.current;
  ++s.moves;
  return stats;
}

MoveStats MovingVolume::finish_shipping() {
  Impl& s = *impl_;
  s.wait_shipping();
  if (!s.ship_pending) return MoveStats{};
  s.ship_pending = false;
  MoveStats stats = s.ship_stats;
  stats.shipping = false;
  return stats;
}

bool MovingVolume::shipping() const { return impl_->ship_pending; }

const PointCloud& MovingVolume::shipped_cloud() const {
  impl_->wait_shipping();
  return impl_->shipped_cloud;
}
const TriangleMesh& MovingVolume::shipped_mesh() const {
  impl_->wait_shipping();
  return impl_->shipped_mesh;
}
std::size_t MovingVolume::moves() const { return impl_->moves; }

void MovingVolume::prepare_final_surface() {
  Impl& s = *impl_;
  if (s.prepared_job.valid()) return;
  s.prepared_times = FinalSurfaceTimes{};
  Impl* impl = &s;
  // After a ship in the background on the same worker, which it then need not wait for: that
  // ship reads the buffer the last move left, this one the current buffer.
  s.prepared_job = ship_worker().submit([impl] {
    require_device(impl->device);  // the worker thread's current device
    impl->prepared_surface = impl->whole_surface(&impl->prepared_times);
  });
}

MovingVolume::SurfaceParts MovingVolume::final_surface_parts(FinalSurfaceTimes* times) const {
  Impl& s = *impl_;
  FinalSurfaceTimes spent;
  SteadyClock::time_point start = SteadyClock::now();
  s.wait_shipping();
  spent.wait_ship_ms = ms_since(start);
  ExtractedSurface live;
  if (s.prepared_job.valid()) {
    start = SteadyClock::now();
    std::future<void> job = std::move(s.prepared_job);
    job.get();  // rethrows what finding it threw
    spent.extract_ms = s.prepared_times.extract_ms;
    spent.assemble_ms = s.prepared_times.assemble_ms;
    spent.prepared = true;
    spent.wait_prepared_ms = ms_since(start);
    live = std::move(s.prepared_surface);
    s.prepared_surface = ExtractedSurface{};
  } else {
    live = s.whole_surface(&spent);
  }
  if (times != nullptr) *times = spent;
  return {&s.shipped_cloud, &s.shipped_mesh, std::move(live)};
}

ExtractedSurface MovingVolume::final_surface(FinalSurfaceTimes* times) const {
  const SurfaceParts parts = final_surface_parts(times);
  const SteadyClock::time_point start = SteadyClock::now();
  ExtractedSurface model;
  model.cloud = join_clouds(*parts.shipped_cloud, parts.live.cloud);
  model.mesh = join_meshes(*parts.shipped_mesh, parts.live.mesh);
  if (times != nullptr) times->join_ms = ms_since(start);
  return model;
}

}  // namespace sls::fusion
