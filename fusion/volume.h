// The Rectangular Parallelepiped Volume (RPV, DESIGN.md section 3): per-axis voxel counts,
// one voxel size and a pose T_world_volume, its voxels (volume_shared.h) in host memory
// (Device::cpu()) or explicit device memory (Device::cuda()).
//
//   Volume volume({960, 960, 960, 10.4e-6, T_world_volume}, VoxelFormat::kCompact, Device::cuda());
//   integrator.integrate(volume, depth, camera, T_world_camera);
//   Volume on_host = volume.to_host();   // for extraction or saving
#pragma once

#include <cstddef>
#include <memory>
#include <string>

#include "fusion/volume_shared.h"
#include "sdk/core/device.h"
#include "sdk/core/pose.h"

namespace sls::fusion {

struct VolumeGeometry {
  int nx = 0, ny = 0, nz = 0;  // voxels per axis
  double voxel_size_m = 0.0;
  Pose T_world_volume;         // the volume's corner (voxel (0,0,0)'s outer corner) and axes

  std::size_t voxel_count() const;
  Eigen::Vector3d size_m() const;  // edge lengths
  // The volume centred on a world point, axes along the world's.
  static VolumeGeometry centred(const Eigen::Vector3d& centre_world, int nx, int ny, int nz, double voxel_size_m);
  // Throws sls::Error(kInvalidArgument) naming the bad value (counts < 2, more than 2^32
  // voxels, a voxel size that is not positive and finite).
  void validate() const;
};

// Where the running average A of the frames lives (DESIGN.md section 3, the paper's (2)).
enum class AverageStorage : std::int32_t {
  kInU = 0,      // U is A: standard TSDF
  kSeparate = 1, // A has its own array (U's type) and U is GTSDF's regularised field
};

// Bytes per voxel: 8 or 3, plus 4 or 2 with a separate running average.
std::size_t bytes_per_voxel(VoxelFormat format, AverageStorage average = AverageStorage::kInU);
const char* voxel_format_name(VoxelFormat format);
// "float32" or "compact"; sls::Error(kInvalidArgument) otherwise.
VoxelFormat parse_voxel_format(const std::string& name);

class Volume {
 public:
  // Allocates and clears (W = 0: nothing observed). Throws sls::Error(kOutOfMemory) naming
  // the size and what is free when it does not fit (host or GPU), kUnsupported for CUDA in a
  // build without it. GTSDF integration needs AverageStorage::kSeparate.
  Volume(const VolumeGeometry& geometry, VoxelFormat format, const Device& device,
         AverageStorage average = AverageStorage::kInU);
  ~Volume();
  Volume(Volume&&) noexcept;
  Volume& operator=(Volume&&) noexcept;

  const VolumeGeometry& geometry() const;
  VoxelFormat format() const;
  AverageStorage average_storage() const;
  const Device& device() const;
  std::size_t bytes() const;

  void clear();                                 // every voxel unobserved
  void set_pose(const Pose& T_world_volume);    // moves the volume (its voxels keep their values)
  // Pointers on the volume's device (host pointers for a CPU volume). Valid while the volume lives.
  VolumeView view() const;
  // A CPU copy (same geometry, format and average storage); a CPU volume is copied as well.
  Volume to_host() const;
  // Copies all voxels from another volume of the same geometry, format and average storage
  // (any devices).
  void copy_from(const Volume& other);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// The view's pose fields from a Pose (float, both directions).
void set_view_pose(VolumeView* view, const Pose& T_world_volume);

}  // namespace sls::fusion
