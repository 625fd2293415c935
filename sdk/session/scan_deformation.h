// The scan's online deformation (paper section IV, DESIGN.md section 3): the deformation graph
// (fusion/deformation) fed while the scan runs and solved beside the frame loop, on a worker
// thread of its own, so the frame loop never waits for it.
//
// The frame loop (ScanSession::add_frame) hands it, over the scan's first revolution
// (DeformationOptions::first_revolution_only)
//   - a keyframe when the scan's focus point has moved node_spacing_m from the last node's
//     (or the camera turned node_angle_deg): a node there, and the frame's surface samples;
//   - every part of the map the moving volume ships, sampled;
//   - on a turntable with known repeatability, every fused frame's table angle since the first
//     frame, a prior on its pose's rotation (DeformationOptions::turntable_rotation_priors).
// The worker, per keyframe, adds the node, matches the keyframe's samples (deformed by the
// graph as it stands) to the shipped samples of parts at least revisit_gap_nodes older —
// surface the scan sees again, e.g. the start of a turntable revolution at its end — closest
// point within max_correspondence_m with normals that agree and the point-to-plane distance
// within it, and makes each match an E_con term (point-to-plane, both sides deformed by the
// nodes of their own time); then online_iterations Gauss–Newton steps.
//
// Tracking goes on in the frame it tracked in (the volume is never moved by the graph): the
// graph maps that frame to the corrected one, so what the worker computes changes no frame's
// fusion, and a scan gives the same model however the worker keeps up. Results deformed by it:
// the map (deform_surface), the poses (deform_pose), and the loop closure's refinement
// (ScanSession::close_loop, which registers the last frame to the first's surface and adds
// those constraints here).
//
// Thread safety: the frame loop's calls (wants_keyframe, add_keyframe, add_rotation_prior,
// add_shipped, status) may run while the worker solves; everything else needs the worker idle
// (drain() first).
#pragma once

#include <cstddef>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "fusion/deformation/deformation_graph.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/image.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/pose.h"

namespace sls::session {

struct DeformationOptions {
  bool enabled = true;            // online deformation (and the loop closure it allows)
  // Keyframes (nodes): when the focus point has moved this far from the last node's (0: a
  // quarter of the volume's smallest extent) or the camera turned this far from its rotation.
  double node_spacing_m = 0.0;
  double node_angle_deg = 5.0;
  // E_reg's region radius ρ (deformation_graph.h; 0: half the volume's largest extent, the
  // view a keyframe's pose was registered over).
  double region_radius_m = 0.0;
  int online_iterations = 2;      // Gauss–Newton steps per keyframe
  int loop_iterations = 3;        // the loop closure's steps (the paper: one)
  // The loop closure registers this many of the last fused frames to the first frame's
  // surface (each kept as a depth map until then: on a GPU at 4000 x 3000, 48 MB each). Two:
  // on the decoded demo revolutions the screw's model C2C 4.1 -> 2.5 µm against one, its loop
  // 0.8 -> 1.1 µm, the knob's unchanged; more frames pull the last pose towards the older
  // frames' registrations and the loop error grows (docs/benchmarks.md).
  int loop_frames = 2;
  // Revisits: shipped parts bound only to nodes at least this many older than the keyframe.
  int revisit_gap_nodes = 16;
  // With the turntable's angles used as the tracker's prior (ScanSessionOptions::
  // turntable_prior, the calibration's σ known): each fused frame's pose also carries the
  // table's rotation since the first frame as a prior (DeformationGraph::add_rotation_prior).
  // Tracking drifts slowly about the axis (±0.015° mid-revolution on the demo screw, 15 µm at
  // the camera) while each table angle is off by its σ alone; the loop closure's constraints
  // correct the revolution's end, these its middle (docs/benchmarks.md).
  bool turntable_rotation_priors = true;
  // The graph covers the scan's first revolution and one volume move's rotation more (how far
  // the scan turned: ScanSession::turned_deg()); later frames add no node and no prior and are
  // bound to its last nodes: by then they track against the closed model, which does not let
  // drift grow, and a session that circles the object revolution after revolution keeps a
  // graph of bounded size and solve time (docs/benchmarks.md, "Soak"). false: a node per
  // keyframe however long the scan runs.
  bool first_revolution_only = true;
  double max_correspondence_m = 0.0;  // 0: 10 voxels
  double max_normal_angle_deg = 30.0;
  int keyframe_samples = 2048;        // surface samples of a frame (a grid over its depth map)
  int max_constraints_per_keyframe = 256;
  double shipped_sample_spacing_m = 0.0;  // shipped parts thinned to one sample per cell (0: 4 voxels)
  // The energies' weights, from two lengths (the graph's are unit-free in its length scale L,
  // the node spacing): a constraint's noise σ_con (0: 2 voxels, the fused surface's), and how
  // far neighbouring nodes' deformations may disagree over a link σ_link (0: σ_con / 10: drift
  // grows slowly from keyframe to keyframe, while one constraint is one noisy surface point).
  // Then γ = (L / σ_link)², w_con = (L / σ_con)², and w_rot = γ ρ² / (3 L²): a node's A
  // straying from a rotation costs what the same change of A between two linked nodes does.
  double constraint_sigma_m = 0.0;
  double link_sigma_m = 0.0;
  // The graph's other settings (nearest nodes, window, links, pins, damping); its length
  // scale, region radius and weights come from the above.
  fusion::deformation::GraphOptions graph;
  // Throws sls::Error(kInvalidArgument) naming the bad value.
  void validate() const;
};

// Surface samples: points and their normals (out of the surface, towards the camera that saw it).
struct SurfaceSamples {
  std::vector<Eigen::Vector3f> points;
  std::vector<Eigen::Vector3f> normals;
};

// About `count` samples of a depth map (camera-frame z, 0 = none) on a regular grid of pixels,
// in the camera frame, each with the normal of its 5-pixel cross (a sample whose neighbours
// lack depth or lie more than `max_step_m` away along the ray is skipped). Made for one camera
// and count, it samples every keyframe's map at the same pixels: their rays are unprojected
// once (through the lens model: ~0.6 ms a keyframe at the default count when made each time).
class DepthMapSampler {
 public:
  // For maps of camera.width x camera.height.
  DepthMapSampler(const CameraIntrinsics& camera, int count);

  // The rows it reads (each grid row and the rows of its crosses' arms): a map on a GPU needs
  // only these on the host (~2 % of a 12 MP map at the default count). Empty for a map too
  // small, or no samples.
  const std::vector<RowSet>& rows() const { return rows_; }
  // From the whole map (the camera's size; sls::Error(kInvalidArgument) for another).
  SurfaceSamples sample(const Image32f& depth_m, double max_step_m) const;
  // From rows() alone, one set after another (Image::gather_rows_from): the same samples, bit
  // for bit. sls::Error(kInvalidArgument) for an image of another size.
  SurfaceSamples sample_gathered(const Image32f& rows_m, double max_step_m) const;

 private:
  // row_of(set, k): the k-th grid row of rows()[set] (0: the arms above, 1: the centres, 2: the
  // arms below).
  template <typename RowOf>
  SurfaceSamples sample_rows(const RowOf& row_of, double max_step_m) const;

  int width_ = 0, height_ = 0;
  int stride_ = 0, arm_ = 2, first_ = 0, columns_ = 0, grid_rows_ = 0;
  std::vector<RowSet> rows_;
  // Per grid position (row-major), its own and its cross's rays (centre, left, right, up, down);
  // NaN where the lens model has none.
  std::vector<Eigen::Vector3d> rays_;
};

// DepthMapSampler(camera of depth_m's size, count).sample(depth_m, max_step_m).
SurfaceSamples sample_depth_map(const Image32f& depth_m, const CameraIntrinsics& camera, int count,
                                double max_step_m);

// What the worker did for one keyframe.
struct KeyframeSolve {
  int frame = 0;
  int node = 0;
  std::size_t matches = 0;          // new E_con terms from revisited surface
  std::size_t constraints = 0;      // all E_con terms after it
  fusion::deformation::SolveStats solve;  // iterations 0 when there was nothing to solve yet
  double match_ms = 0.0;            // finding the matches
  double ms = 0.0;                  // the whole job on the worker
};

// A snapshot for the frame loop's reports.
struct DeformationStatus {
  std::size_t nodes = 0;
  std::size_t constraints = 0;
  std::size_t keyframes_done = 0;
  std::size_t pending = 0;          // jobs queued or running
  double last_solve_ms = 0.0;       // the last keyframe's job on the worker
  double worker_ms = 0.0;           // all jobs so far
  std::string error;                // a solve that failed (the graph keeps its last transforms)
};

class ScanDeformation {
 public:
  // length_scale_m: node spacing (GraphOptions::length_scale_m); region_radius_m: ρ; voxel_size_m:
  // for the automatic correspondence distance and sample spacing. Starts the worker.
  ScanDeformation(const DeformationOptions& options, double node_spacing_m, double region_radius_m,
                  double voxel_size_m);
  ~ScanDeformation();  // stops the worker (after its current job)
  ScanDeformation(const ScanDeformation&) = delete;
  ScanDeformation& operator=(const ScanDeformation&) = delete;

  const DeformationOptions& options() const;
  double node_spacing_m() const;
  double constraint_sigma_m() const;  // σ_con as resolved (the options' or 2 voxels)

  // Frame loop: whether a frame at this pose (focus point given) makes a keyframe.
  bool wants_keyframe(const Pose& T_world_camera, const Eigen::Vector3d& focus_point) const;
  // Frame loop: a keyframe (its samples in its camera frame), queued for the worker; with a
  // prior on its pose's rotation (DeformationGraph::add_rotation_prior: a turntable's angle
  // since the first frame), when one is known.
  void add_keyframe(int frame, const Pose& T_world_camera, const Eigen::Vector3d& focus_point,
                    SurfaceSamples samples_camera,
                    std::optional<fusion::deformation::RotationPrior> rotation_prior = std::nullopt);
  // Frame loop: a prior on the rotation of a frame that makes no keyframe (as add_keyframe's).
  void add_rotation_prior(int frame, const Eigen::Vector3d& focus_point,
                          const fusion::deformation::RotationPrior& prior);
  // Frame loop: a part of the map shipped at `frame` (world points and normals), queued.
  void add_shipped(int frame, const PointCloud& cloud, std::size_t begin, std::size_t end);
  DeformationStatus status() const;

  // Waits until the worker has done every job queued.
  void drain();

  // With the worker idle (after drain()):
  const fusion::deformation::DeformationGraph& graph() const;
  fusion::deformation::DeformationGraph& graph();
  std::vector<KeyframeSolve> keyframe_solves() const;
  // A pose of frame `frame` as deformed (the rigid part of the deformation at its focus point,
  // by the nodes of its time: bind_pose with rotation priors, else bind_around; unchanged
  // without nodes).
  Pose deform_pose(int frame, const Pose& T_world_camera, const Eigen::Vector3d& focus_point) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sls::session
