// The GPU halves of fusion's stages in a build without CUDA: they link, and making one throws
// kUnsupported. (The stages never get there: a volume or a stage on a GPU is refused first,
// by require_device.)
#include "fusion/integrator_gpu.h"
#include "fusion/moving_volume_gpu.h"
#include "sdk/core/error.h"

namespace sls::fusion::detail {

struct MovingVolumeGpu::State {};

MovingVolumeGpu::MovingVolumeGpu(const Device& device, const GpuStream&, const GpuStream&) {
  throw_error(ErrorCode::kUnsupported, "moving volume on {}: this build has no CUDA support", device.to_string());
}
MovingVolumeGpu::~MovingVolumeGpu() = default;
void MovingVolumeGpu::resample(const Volume&, Volume&, const Rigid3f&) {}
ExtractedSurface MovingVolumeGpu::extract_part(const Volume&, const OrientedRegion&, const ExtractOptions&, double*) {
  return {};
}

struct IntegratorGpu::State {};

IntegratorGpu::IntegratorGpu(const Device& device, const GpuStream&) {
  throw_error(ErrorCode::kUnsupported, "integrator on {}: this build has no CUDA support", device.to_string());
}
IntegratorGpu::~IntegratorGpu() = default;
const float* IntegratorGpu::on_device(const Image32f&) { return nullptr; }
DepthMapSummary IntegratorGpu::summarize(const float*, std::size_t) { return {}; }
IntegrationStats IntegratorGpu::integrate(Volume&, const float*, const CameraIntrinsics&, const Pose&, const DepthBand&,
                                          const IntegrationOptions&) {
  return {};
}

}  // namespace sls::fusion::detail
