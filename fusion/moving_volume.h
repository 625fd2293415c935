// The moving, rotating RPV (paper section II, DESIGN.md section 3): a volume whose axes follow
// the camera's (volume x, y, z along camera x, y, z) and whose centre follows the camera's focus
// point (focus_distance_m along the optical axis). When the focus point leaves the central part
// of the volume (margin_fraction of each extent on either side) or the camera has turned more
// than max_rotation_deg from the volume's axes, the volume moves to the camera's current
// placement: the old voxels are resampled into the new pose (trilinear on U over observed
// voxels, weights carried; new space is unobserved), and the surface of every part of the old
// volume that falls outside the new one is extracted (zero crossings with normals and weights,
// and its marching-cubes triangles) and shipped to host memory. Two voxel buffers (ping-pong)
// live on the volume's device; resampling and the shipping extraction run there (CPU loops or
// CUDA kernels over one per-voxel body, resample_shared.h).
//
//   MovingVolume moving(geometry_counts_and_voxel, VoxelFormat::kCompact, Device::cuda(), options);
//   moving.place(T_world_camera_first);
//   per frame: integrate into moving.volume(); MoveStats s = moving.follow(T_world_camera);
//   at the end: ExtractedSurface model = moving.final_surface();
#pragma once

#include <cstddef>
#include <memory>

#include "fusion/extract.h"
#include "fusion/volume.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/pose.h"

namespace sls::fusion {

struct MovingVolumeOptions {
  double focus_distance_m = 0.1;   // the volume centre's distance along the optical axis
  double margin_fraction = 0.15;   // move when the focus leaves the central 1 - 2 * margin of an extent
  // Or when the camera's axes turned this far from the volume's. Every turning move resamples
  // the whole volume (trilinear), which low-passes the model a little each time: measured on
  // the exact-depth demo revolution of the knurled screw (120 frames, 3° steps), 5° (59 moves)
  // gave C2C 24 µm and a loop error of 0.25°, 15° (20 moves) 9 µm and 0.11°, 2.5° (119
  // moves) 0.53°. 15° is about the most the default box (the field at the focus, half its
  // width deep) allows: the field's edges then swing in depth by tan 15° · half the width,
  // about half the box's half-depth, each way, leaving the rest for the surface's relief.
  double max_rotation_deg = 15.0;
  // Revisited surface (fusion/revisit_filter.h): true ships only surface no earlier move
  // shipped (cells of two voxels, per facing direction), so a session that circles the object
  // many times keeps one copy and its model stays bounded by the object's surface; false
  // (default: what every measured figure used) ships every pass, and a second revolution adds
  // a second copy, until start_merging_revisits() (the scan session's policy, RevisitPolicy).
  bool merge_revisits = false;
  // A move's leaving surface is shipped (on a GPU found on a stream of its own, downloaded,
  // assembled, appended) on a worker thread while the caller goes on; move_to() returns after
  // the resampling. What reads the shipped surface waits for it: shipped_cloud(),
  // shipped_mesh(), final_surface(), the next move, and finish_shipping(), which also gives the
  // ship's figures. The volume the ship reads is the one the move left, which nothing writes
  // until the next move. false: shipped before move_to() returns. (The scan session ships in
  // the background on a GPU only: on the CPU the worker would share the frame loop's cores.)
  bool ship_in_background = false;
  ExtractOptions extract;          // for the shipped surface and final_surface()
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate() const;
};

struct MoveStats {
  bool moved = false;
  // Shipped in the background (MovingVolumeOptions::ship_in_background): the shipped_* and
  // ship_* figures below are finish_shipping()'s to give.
  bool shipping = false;
  double translation_m = 0.0;       // of the volume centre
  double rotation_deg = 0.0;        // of the volume axes
  std::size_t shipped_points = 0;   // points shipped by this move
  std::size_t shipped_triangles = 0;
  double resample_ms = 0.0;
  double ship_ms = 0.0;             // extraction of the leaving part and its copy to the host
  double ship_assemble_ms = 0.0;    // of ship_ms: assembling the points and triangles on the host (CUDA)
};

// Where MovingVolume::final_surface() spent its time (ms, wall): waiting for a ship still running
// in the background; finding the current volume's surface and bringing it to the host (of it, the
// host's assembly of its points and triangles); copying the shipped parts and it into one model.
// A surface found beforehand (prepare_final_surface()) was found beside the caller's work:
// extract_ms and assemble_ms are then its figures, and wait_prepared_ms what final_surface()
// still waited for it.
struct FinalSurfaceTimes {
  double wait_ship_ms = 0.0;
  double extract_ms = 0.0;
  double assemble_ms = 0.0;
  double join_ms = 0.0;
  bool prepared = false;
  double wait_prepared_ms = 0.0;
};

class MovingVolume {
 public:
  // counts and voxel size of the volume; its pose comes from place(). Allocates both buffers
  // (sls::Error(kOutOfMemory) as Volume's when they do not fit). GTSDF integration needs
  // AverageStorage::kSeparate; moves resample A with U. On a GPU, resampling is queued on
  // `stream` (the session's frame stream, after the frames' integration) and shipping on
  // `ship_stream` (beside it); each is one of its own when none is given.
  MovingVolume(int nx, int ny, int nz, double voxel_size_m, VoxelFormat format, const Device& device,
               const MovingVolumeOptions& options, AverageStorage average = AverageStorage::kInU,
               const GpuStream& stream = {}, const GpuStream& ship_stream = {});
  ~MovingVolume();
  MovingVolume(MovingVolume&&) noexcept;
  MovingVolume& operator=(MovingVolume&&) noexcept;

  const MovingVolumeOptions& options() const;
  // The volume pose for a camera pose: axes along the camera's, centred on its focus point.
  Pose placement(const Pose& T_world_camera) const;
  // Starts a scan: clears the volume, forgets what was shipped (and the move count) and
  // places the volume for this camera pose (the first frame).
  void place(const Pose& T_world_camera);

  // The mutable volume waits for a surface being prepared (prepare_final_surface()) and drops
  // it: the caller may change the volume.
  Volume& volume();
  const Volume& volume() const;

  // Whether follow() would move for this camera pose: the focus point has left the margin or
  // the camera turned too far (see above).
  bool needs_move(const Pose& T_world_camera) const;
  // Moves when needs_move().
  MoveStats follow(const Pose& T_world_camera);
  // Moves to this pose unconditionally (resample + ship). What ships: the old volume's
  // crossings whose point lies outside the new volume's sample box (the hull of its voxel
  // centres, where the new volume's own crossings lie: the two never overlap) and the
  // marching-cubes triangles of the old cells whose centre does (extract.h's OrientedRegion).
  // Resampling: resample_shared.h (which voxels stay observed, how weights are carried).
  MoveStats move_to(const Pose& T_world_volume);

  // A move shipping in the background: waits for its ship and returns that move's stats with
  // its ship figures (shipping false), once; MoveStats{} when none is pending. Rethrows what
  // the ship threw.
  MoveStats finish_shipping();
  // Whether a move's ship has not been collected by finish_shipping() yet.
  bool shipping() const;

  // From now on ships only surface no earlier move shipped, as merge_revisits does, counting
  // what was shipped so far as shipped (so a later pass over it adds nothing). Until the next
  // place(). Waits for a ship in the background first.
  void start_merging_revisits();
  bool merging_revisits() const;

  // Everything shipped so far (world frame), in shipping order (a ship in the background
  // waited for).
  const PointCloud& shipped_cloud() const;
  const TriangleMesh& shipped_mesh() const;
  std::size_t moves() const;

  // The model: the shipped parts plus the current volume's surface (cloud and mesh, world frame).
  // `times`, when given: where the time went (FinalSurfaceTimes).
  ExtractedSurface final_surface(FinalSurfaceTimes* times = nullptr) const;
  // The same in pieces, not joined: the shipped parts as the volume holds them (valid until
  // the next move or place()) and the current volume's surface. For a caller that writes the
  // model in one pass of its own (the scan session's deformed model); join_ms is left 0.
  struct SurfaceParts {
    const PointCloud* shipped_cloud = nullptr;
    const TriangleMesh* shipped_mesh = nullptr;
    ExtractedSurface live;
  };
  SurfaceParts final_surface_parts(FinalSurfaceTimes* times = nullptr) const;
  // Starts finding the current volume's surface on the ship worker (after a ship in the
  // background; on a GPU on the ship stream), while the caller goes on: the scan session
  // calls it as its loop closure starts, whose registrations and solve do not change the
  // volume. The next final_surface() or final_surface_parts() takes it (the same surface, bit
  // for bit) instead of finding it, and rethrows what finding it threw. volume() (mutable),
  // move_to() and place() wait for it and drop it. Nothing when one is prepared already.
  void prepare_final_surface();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::fusion
