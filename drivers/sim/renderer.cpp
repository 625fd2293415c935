#include "drivers/sim/renderer.h"

#include <cmath>
#include <limits>

#include "drivers/sim/render_backend.h"
#include "sdk/core/error.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/pattern_set.h"

namespace sls::sim {
namespace {

// The CPU backend: loops over the shared per-pixel functions (OpenMP when available).
class CpuRenderBackend final : public RenderBackend {
 public:
  explicit CpuRenderBackend(const RayMap& rays)
      : rays_(rays),
        width_(rays.width),
        height_(rays.height),
        geometry_(rays.rays.size()),
        blur_(rays.rays.size()),
        electrons_(rays.rays.size()),
        blurred_rows_(rays.rays.size()) {}

  void trace(const FrameRenderParams& params) override {
    const long count = static_cast<long>(geometry_.size());
#pragma omp parallel for schedule(dynamic, 4096)
    for (long i = 0; i < count; ++i) {
      const auto index = static_cast<std::size_t>(i);
      geometry_[index] = trace_pixel(params, rays_.rays[index], rays_.valid[index] != 0);
      const float sigma = geometry_[index].camera_sigma_px;
      blur_[index] = blur_radius(sigma) > 0 ? blur_recurrence(sigma) : BlurRecurrence{};
    }
  }

  void render_pattern(const PatternRenderParams& params, std::uint16_t* out) override {
    const long count = static_cast<long>(geometry_.size());
    // The pattern's levels once per image, not a cos per level and pixel: the same values.
    levels_ = pattern_levels(params.pattern);
    const PatternLevelTable table{levels_.data(), params.pattern.extent};
#pragma omp parallel for schedule(static)
    for (long i = 0; i < count; ++i) {
      const auto index = static_cast<std::size_t>(i);
      electrons_[index] = pattern_electrons(geometry_[index], table, params.pattern.axis, params.projector);
    }
#pragma omp parallel for schedule(static)
    for (int y = 0; y < height_; ++y) {
      const float* line = electrons_.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(width_);
      for (int x = 0; x < width_; ++x) {
        const std::size_t index = pixel_index(x, y);
        blurred_rows_[index] =
            blur_gather_1d(line, width_, 1, x, blur_radius(geometry_[index].camera_sigma_px), blur_[index]);
      }
    }
    image_.resize(geometry_.size());
#pragma omp parallel for schedule(static)
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        const std::size_t index = pixel_index(x, y);
        const float electrons = blur_gather_1d(blurred_rows_.data() + x, height_, width_, y,
                                               blur_radius(geometry_[index].camera_sigma_px), blur_[index]);
        NoiseKey key = params.key;
        key.pixel = static_cast<std::uint32_t>(index);
        image_[index] = pixel_digital_number(params.sensor, exposed_electrons(params, electrons), key, params.noise);
      }
    }
    if (out != nullptr) std::copy(image_.begin(), image_.end(), out);
  }

  void download_geometry(PixelGeometry* out) const override { std::copy(geometry_.begin(), geometry_.end(), out); }

  void render_depth(const NoiseKey& key, float* out) override {
    const long count = static_cast<long>(geometry_.size());
#pragma omp parallel for schedule(static)
    for (long i = 0; i < count; ++i) {
      NoiseKey pixel_key = key;
      pixel_key.pixel = static_cast<std::uint32_t>(i);
      out[i] = noisy_depth(geometry_[static_cast<std::size_t>(i)], pixel_key);
    }
  }

  void synchronize() override {}

 private:
  std::size_t pixel_index(int x, int y) const {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x);
  }

  const RayMap& rays_;
  int width_;
  int height_;
  std::vector<PixelGeometry> geometry_;
  // Each pixel's blur weights, made with its geometry: the same for every image of the frame.
  std::vector<BlurRecurrence> blur_;
  std::vector<std::uint8_t> levels_;
  std::vector<float> electrons_;
  std::vector<float> blurred_rows_;
  std::vector<std::uint16_t> image_;
};

Rigid3d to_rigid(const Pose& pose) { return pose.to_rigid3d(); }

FrameRenderParams frame_params(const SimRig& rig, const Scene& scene, int frame) {
  FrameRenderParams params{};
  params.scene = scene.shape();
  params.camera = rig.camera;
  params.projector = rig.projector;
  const Pose T_object_camera = rig.T_object_camera(frame);
  const Pose T_object_projector = T_object_camera * rig.T_camera_projector;
  params.T_object_camera = to_rigid(T_object_camera);
  params.T_projector_object = to_rigid(T_object_projector.inverse());
  const Eigen::Vector3d projector_centre = T_object_projector.translation();
  params.projector_centre_object = {projector_centre.x(), projector_centre.y(), projector_centre.z()};
  params.camera_sensor = rig.optics.camera_sensor;
  params.camera_lens = rig.optics.camera_lens;
  params.projector_optics = rig.optics.projector;
  // white_electrons is defined for a target facing the camera, lit at the triangulation angle.
  params.cos_reference = std::cos(rig.optics.triangulation_angle_rad);
  params.ambient_electrons = rig.optics.ambient_electrons;
  params.shadow_offset_m = 1e-7;
  params.material = rig.material;
  const DecodeOptions decode;  // the decoder's defaults: what it keeps
  params.decode_min_modulation_ratio = decode.min_modulation_ratio;
  params.decode_max_phase_sigma_px = decode.max_phase_sigma_px;
  params.decode_min_sin_angle = std::sin(decode.min_triangulation_angle_deg * M_PI / 180.0);
  for (const PatternDesc& pattern : rig.patterns.patterns) {
    if (pattern.kind == PatternKind::kPhaseShift && pattern.axis == PatternAxis::kColumns) {
      params.phase_period_px = pattern.period_px;
      params.phase_steps = pattern.steps;
      break;
    }
  }
  return params;
}

}  // namespace

std::unique_ptr<RenderBackend> make_cpu_render_backend(const RayMap& rays) {
  return std::make_unique<CpuRenderBackend>(rays);
}

Renderer::Renderer(SimRig rig, Scene scene, const Device& device)
    : rig_(std::move(rig)), scene_(std::move(scene)), device_(device) {
  require_device(device_);
  validate_pattern_set(rig_.patterns);
  static_assert(sizeof(PixelGeometry) == 48, "PixelGeometry is uploaded as raw bytes");
  rays_ = std::make_unique<RayMap>(compute_ray_map(rig_.camera, device_));
  if (device_.is_cuda()) {
    backend_ = make_cuda_render_backend(*rays_, device_.id);
  } else {
    backend_ = make_cpu_render_backend(*rays_);
  }
}

Renderer::~Renderer() = default;
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

void Renderer::require_frame() const {
  if (frame_ < 0) throw_error(ErrorCode::kInvalidArgument, "renderer: call set_frame() before rendering");
}

void Renderer::set_frame(int frame) {
  if (frame < 0) throw_error(ErrorCode::kInvalidArgument, "renderer: frame {} is negative", frame);
  backend_->trace(frame_params(rig_, scene_, frame));
  frame_ = frame;
}

int Renderer::add_placement(const ObjectPlacement& placement) {
  rig_.placements.push_back(placement);
  return static_cast<int>(rig_.placements.size()) - 1;
}

namespace {

PatternRenderParams pattern_params(const SimRig& rig, int frame, const PatternDesc& pattern, std::uint32_t image_key) {
  PatternRenderParams params;
  params.pattern = pattern;
  params.sensor = rig.optics.camera_sensor;
  params.projector = rig.optics.projector;
  params.key.seed = rig.noise_seed;
  params.key.frame = static_cast<std::uint32_t>(frame);
  params.key.image = image_key;
  params.noise = rig.noise;
  return params;
}

const PatternDesc& pattern_at(const SimRig& rig, int pattern) {
  if (pattern < 0 || static_cast<std::size_t>(pattern) >= rig.patterns.size()) {
    throw_error(ErrorCode::kInvalidArgument, "renderer: pattern {} of a set of {}", pattern, rig.patterns.size());
  }
  return rig.patterns.patterns[static_cast<std::size_t>(pattern)];
}

}  // namespace

Image16u Renderer::render_pattern(int pattern) {
  return render(pattern_at(rig_, pattern), static_cast<std::uint32_t>(pattern));
}

Image16u Renderer::render_pattern(int pattern, double exposure_scale, int exposure_index) {
  if (exposure_index < 0 || exposure_index > 255) {
    throw_error(ErrorCode::kInvalidArgument, "renderer: exposure index {} outside 0..255", exposure_index);
  }
  // Above the 16 bits of pattern indices (kDepthImage included): another exposure's noise.
  const std::uint32_t key = static_cast<std::uint32_t>(pattern) | (static_cast<std::uint32_t>(exposure_index) << 16);
  return render(pattern_at(rig_, pattern), key, exposure_scale);
}

Image16u Renderer::render(const PatternDesc& pattern, std::uint32_t image_key, double exposure_scale) {
  require_frame();
  if (!(std::isfinite(exposure_scale) && exposure_scale > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "renderer: exposure scale {} must be finite and positive",
                exposure_scale);
  }
  Image16u image(rig_.camera.width, rig_.camera.height, 0, image_memory_);
  PatternRenderParams params = pattern_params(rig_, frame_, pattern, image_key);
  params.exposure = exposure_scale;
  backend_->render_pattern(params, image.data());
  return image;
}

void Renderer::render_pattern_resident(int pattern) {
  require_frame();
  backend_->render_pattern(
      pattern_params(rig_, frame_, pattern_at(rig_, pattern), static_cast<std::uint32_t>(pattern)), nullptr);
}

void Renderer::synchronize() { backend_->synchronize(); }

GroundTruthFrame Renderer::ground_truth() const {
  require_frame();
  const int width = rig_.camera.width, height = rig_.camera.height;
  std::vector<PixelGeometry> geometry(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  backend_->download_geometry(geometry.data());
  GroundTruthFrame truth;
  truth.frame = frame_;
  truth.commanded_angle_deg = rig_.commanded_angle_deg(frame_);
  truth.true_angle_deg = rig_.true_angle_deg(frame_);
  truth.T_world_object = rig_.T_world_object(frame_);
  truth.T_object_camera = rig_.T_object_camera(frame_);
  truth.depth_m = Image32f(width, height);
  truth.projector_u = Image32f(width, height, std::numeric_limits<float>::quiet_NaN());
  truth.projector_v = Image32f(width, height, std::numeric_limits<float>::quiet_NaN());
  truth.valid = Image8u(width, height);
  truth.depth_sigma_m = Image32f(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const PixelGeometry& g = geometry[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                                        static_cast<std::size_t>(x)];
      truth.depth_m(x, y) = g.depth_m;
      if (g.flags & kPixelLit) {
        truth.projector_u(x, y) = g.projector_u;
        truth.projector_v(x, y) = g.projector_v;
        truth.valid(x, y) = 1;
        truth.depth_sigma_m(x, y) = g.depth_sigma_m;
      }
    }
  }
  return truth;
}

Image32f Renderer::render_depth() {
  require_frame();
  Image32f depth(rig_.camera.width, rig_.camera.height);
  NoiseKey key;
  key.seed = rig_.noise_seed;
  key.frame = static_cast<std::uint32_t>(frame_);
  key.image = kDepthImage;
  backend_->render_depth(key, depth.data());
  if (!rig_.noise) {
    // Noise off: the true depth where valid.
    const GroundTruthFrame truth = ground_truth();
    for (int y = 0; y < depth.height(); ++y)
      for (int x = 0; x < depth.width(); ++x) depth(x, y) = truth.valid(x, y) ? truth.depth_m(x, y) : 0.0f;
  }
  return depth;
}

}  // namespace sls::sim
