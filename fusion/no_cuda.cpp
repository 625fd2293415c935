// The GPU halves of fusion's stages in a build without CUDA: they link, and making one throws
// kUnsupported. (The stages never get there: a volume or a stage on a GPU is refused first,
// by require_device.)
#include "fusion/integrator_gpu.h"
#include "fusion/moving_volume_gpu.h"
#include "fusion/raycaster_gpu.h"
#include "fusion/tracker_internal.h"
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

void raycast_gpu(const VolumeView&, const RaycastParams&, const RaycastGuideView&, const Rigid3f&, const Vec3f*, int, int,
                 const RaycastOutputsDevice&, const GpuStream&) {
  throw_error(ErrorCode::kUnsupported, "raycast on a GPU: this build has no CUDA support");
}
void raycast_guide_tiles_gpu(const float*, int, int, int, int, float*, float*, const GpuStream&) {
  throw_error(ErrorCode::kUnsupported, "raycast on a GPU: this build has no CUDA support");
}

}  // namespace sls::fusion::detail

namespace sls::fusion {

struct Tracker::Impl::Gpu {};
void Tracker::Impl::GpuDelete::operator()(Gpu* gpu) const { delete gpu; }
void Tracker::Impl::allocate_on_device() {}  // track() says what is missing

TrackingResult Tracker::Impl::track_gpu(const Image32f&, const Image<Vec3f>&, const Image<Vec3f>&, const Pose&,
                                        const Pose&, const Image32f*, const Image32f*) {
  throw_error(ErrorCode::kUnsupported, "tracking: CUDA asked of a build without CUDA");
}
void Tracker::Impl::set_reference_gpu(const Image32f&, const Image32f&, const Pose&) {
  throw_error(ErrorCode::kUnsupported, "tracking: CUDA asked of a build without CUDA");
}

}  // namespace sls::fusion
