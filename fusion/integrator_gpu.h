// Internal: the integrator's GPU half (fusion/integrator.h): its device buffers (the uploaded
// depth map, GTSDF's active-voxel lists and their sort, the depth summary's) and launches.
// Declared in every build, without CUDA's headers; defined in fusion/cuda/integrator_gpu.cpp,
// or in a build without CUDA by fusion/no_cuda.cpp, where making one throws kUnsupported.
#pragma once

#include <cstddef>
#include <memory>

#include "fusion/integrator.h"

namespace sls::fusion::detail {

class IntegratorGpu {
 public:
  IntegratorGpu(const Device& device, const GpuStream& stream);
  ~IntegratorGpu();
  IntegratorGpu(const IntegratorGpu&) = delete;
  IntegratorGpu& operator=(const IntegratorGpu&) = delete;

  // `depth_m` on the GPU: itself where it lives there, else uploaded into a buffer kept for the
  // next frame.
  const float* on_device(const Image32f& depth_m);
  // integration_depth_band's figures of a map on the GPU, computed there: only they come to the host.
  DepthMapSummary summarize(const float* depth_device, std::size_t pixels);
  // The frame into `volume` over `band`, GTSDF's sweeps included, before returning. The inputs
  // are checked by the caller (Integrator::integrate).
  IntegrationStats integrate(Volume& volume, const float* depth_device, const CameraIntrinsics& camera,
                             const Pose& T_world_camera, const DepthBand& band, const IntegrationOptions& options);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace sls::fusion::detail
