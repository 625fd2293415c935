// Surface extraction from the fusion volume (paper section III-C, DESIGN.md section 3):
//
//   extract_points  the paper's cloud: one point per grid edge where U changes sign between
//                   two observed voxels, at the linearly interpolated zero, with the normal
//                   of the trilinear field there and the smaller of the two weights;
//   extract_mesh    a marching-cubes mesh (fusion/marching_cubes_tables.h) over cells whose
//                   eight corners are observed; its vertices are exactly those crossings,
//                   shared by every cell around their edge, so the mesh is closed wherever
//                   the observed region is.
//
// Both are in the WORLD frame (the volume's T_world_volume applied in double precision).
// Per point / vertex: normal (unit, out of the solid), confidence = min(1, weight /
// ExtractOptions::full_confidence_weight), and the raw weight as the float property
// "weight". Write them with sls::write_ply (sdk/core/ply.h): binary little-endian with
// normals, confidence and weight.
//
//   Volume on_host = volume.to_host();                  // a CUDA volume: copy first
//   PointCloud cloud = extract_points(on_host);         // or both at once:
//   ExtractedSurface surface = extract_surface(on_host);
//   write_ply(out + "/cloud.ply", surface.cloud);
//   write_ply(out + "/mesh.ply", surface.mesh);
//
// The CPU loops run on OpenMP threads (z slices for the crossings, chunks of the cells next to
// a crossing for the mesh); the output order is deterministic (z, y, x, axis), whatever the
// thread count.
#pragma once

#include <Eigen/Core>

#include "fusion/volume.h"
#include "sdk/core/point_cloud.h"
#include "sdk/core/pose.h"

namespace sls::fusion {

struct ExtractOptions {
  // Voxels observed fewer times than this take no part (1: every observed voxel; W = 0 never does).
  float min_weight = 1.0f;
  // The weight at which a point's confidence reaches 1. Only scales the confidence channel;
  // the raw weight is always in the "weight" property.
  float full_confidence_weight = 20.0f;
};

// An axis-aligned box in the world frame, bounds included.
struct Box {
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  bool contains(const Eigen::Vector3d& p) const {
    return p.x() >= min.x() && p.y() >= min.y() && p.z() >= min.z() && p.x() <= max.x() && p.y() <= max.y() &&
           p.z() <= max.z();
  }
};

// An oriented box placed in the world: the points whose coordinates in the box's frame
// (T_world_box) lie in [min, max], bounds included; with keep_outside, everything else. The
// moving volume ships the part of its old surface outside its new placement with one. The
// test runs in float on volume-frame points (extract_shared.h's RegionFilter), the same code
// on the CPU and on the GPU, so both backends keep exactly the same points.
struct OrientedRegion {
  Pose T_world_box;
  Eigen::Vector3d min = Eigen::Vector3d::Zero();
  Eigen::Vector3d max = Eigen::Vector3d::Zero();
  bool keep_outside = false;
};

// The zero-crossing cloud of a CPU volume; with `region`, only the points inside it.
// sls::Error(kInvalidArgument) for a volume that is not on the CPU (call to_host() first) or
// bad options.
PointCloud extract_points(const Volume& volume, const Box* region = nullptr, const ExtractOptions& options = {});

// The marching-cubes mesh of a CPU volume (same errors).
TriangleMesh extract_mesh(const Volume& volume, const ExtractOptions& options = {});

// Both from one pass over the volume (what `sls scan` writes): cheaper than the two calls.
struct ExtractedSurface {
  PointCloud cloud;
  TriangleMesh mesh;
};
ExtractedSurface extract_surface(const Volume& volume, const ExtractOptions& options = {});

// The same over a view of host memory placed at T_world_volume, for callers holding voxels
// that are not a Volume (a resampled buffer of the moving volume).
PointCloud extract_points(const VolumeView& view, const Pose& T_world_volume, const Box* region,
                          const ExtractOptions& options);
TriangleMesh extract_mesh(const VolumeView& view, const Pose& T_world_volume, const ExtractOptions& options);
ExtractedSurface extract_surface(const VolumeView& view, const Pose& T_world_volume, const ExtractOptions& options);

// The part of the surface in an oriented region: the crossings whose point it keeps (cloud,
// in edge-id order) and the marching-cubes triangles of the cells whose centre it keeps (mesh;
// its vertices are the crossings those cells use, a few of them just across the region's
// border, so the part's mesh reaches its rim). Every crossing and every cell belongs to
// exactly one of a region and its complement.
PointCloud extract_points(const VolumeView& view, const Pose& T_world_volume, const OrientedRegion& region,
                          const ExtractOptions& options);
ExtractedSurface extract_surface(const VolumeView& view, const Pose& T_world_volume, const OrientedRegion& region,
                                 const ExtractOptions& options);

}  // namespace sls::fusion
