// The two thin launchers behind sls::sim::Renderer (internal to drivers/sim).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "drivers/sim/render_shared.h"
#include "sdk/core/ray_map.h"

namespace sls::sim {

struct PatternRenderParams {
  PatternDesc pattern;
  SensorModel sensor;
  ProjectorModel projector;
  NoiseKey key;  // pixel field is filled per pixel
  bool noise = true;
  // Exposure time relative to the rig's: every electron (projector and ambient light) scales
  // with it, read noise and the full well do not, so bright pixels saturate (HDR capture).
  double exposure = 1.0;
};

// The mean electrons a pixel collects at the render's exposure (exact at 1).
SLS_HOST_DEVICE inline float exposed_electrons(const PatternRenderParams& params, float electrons) {
  return static_cast<float>(static_cast<double>(electrons) * params.exposure);
}

class RenderBackend {
 public:
  virtual ~RenderBackend() = default;
  virtual void trace(const FrameRenderParams& params) = 0;
  // Renders into the backend's image; when `out` is not null, also copies it there.
  virtual void render_pattern(const PatternRenderParams& params, std::uint16_t* out) = 0;
  virtual void download_geometry(PixelGeometry* out) const = 0;
  // Noisy depth (0 where not lit), keyed like the patterns with image = kDepthImage.
  virtual void render_depth(const NoiseKey& key, float* out) = 0;
  virtual void synchronize() = 0;
};

constexpr std::uint32_t kDepthImage = 0xFFFFu;

std::unique_ptr<RenderBackend> make_cpu_render_backend(const RayMap& rays);
// sim/cuda/render_backend.cu; in a build without CUDA sim/no_cuda.cpp's, which throws
// kUnsupported (never reached: the renderer refuses a GPU first, by require_device).
std::unique_ptr<RenderBackend> make_cuda_render_backend(const RayMap& rays, int device_id);

// The noisy depth of one pixel: one body for both backends.
SLS_HOST_DEVICE inline float noisy_depth(const PixelGeometry& g, NoiseKey key) {
  if (!(g.flags & kPixelDecodable)) return 0.0f;  // the decoder would leave it empty
  NoiseStream stream = make_noise_stream(key, kUserStream + 1);
  return static_cast<float>(static_cast<double>(g.depth_m) + static_cast<double>(g.depth_sigma_m) * stream.normal());
}

}  // namespace sls::sim
