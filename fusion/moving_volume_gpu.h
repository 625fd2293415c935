// Internal: the moving volume's GPU half (fusion/moving_volume.h): the device buffers and
// launches of a move's resampling and of extracting a region's surface on the GPU. Declared in
// every build, without CUDA's headers; defined in fusion/cuda/moving_volume_gpu.cpp, or in a
// build without CUDA by fusion/no_cuda.cpp, where making one throws kUnsupported (a volume on
// a GPU cannot exist there: Volume refuses it first).
#pragma once

#include <memory>

#include "fusion/extract.h"
#include "fusion/volume.h"
#include "sdk/core/gpu_stream.h"

namespace sls::fusion::detail {

class MovingVolumeGpu {
 public:
  // Resampling on `resample_stream` (after the frames' work), extraction on `ship_stream`.
  MovingVolumeGpu(const Device& device, const GpuStream& resample_stream, const GpuStream& ship_stream);
  ~MovingVolumeGpu();
  MovingVolumeGpu(const MovingVolumeGpu&) = delete;
  MovingVolumeGpu& operator=(const MovingVolumeGpu&) = delete;

  // Every voxel of `to` from `from` (resample_voxel), before returning.
  void resample(const Volume& from, Volume& to, const Rigid3f& grid_from_to);
  // The part of `volume`'s surface in `region`: its crossings (and the vertices of its cells)
  // and its surface cells found on the GPU, ordered there, and assembled on the host by the
  // CPU extraction's own code, so the cloud and the mesh are the CPU's point for point.
  // assemble_ms: the host's share of the time.
  ExtractedSurface extract_part(const Volume& volume, const OrientedRegion& region, const ExtractOptions& options,
                                double* assemble_ms);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace sls::fusion::detail
