#include "sdk/decode/decoder.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "sdk/core/error.h"

#include "sdk/decode/decoder_gpu.h"
#include "sdk/decode/stack_check.h"

namespace sls {

namespace {

constexpr double kPi = 3.14159265358979323846;

void require_finite_positive(double value, const char* name) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw_error(ErrorCode::kInvalidArgument, "decode options: {} = {} must be positive and finite", name, value);
  }
}

void require_finite_non_negative(double value, const char* name) {
  if (!(value >= 0.0) || !std::isfinite(value)) {
    throw_error(ErrorCode::kInvalidArgument, "decode options: {} = {} must be >= 0 and finite", name, value);
  }
}

Rigid3f to_rigid3f(const Rigid3d& r) {
  Rigid3f out;
  for (int i = 0; i < 9; ++i) out.rotation.m[i] = static_cast<float>(r.rotation.m[i]);
  out.translation = {static_cast<float>(r.translation.x), static_cast<float>(r.translation.y),
                     static_cast<float>(r.translation.z)};
  return out;
}

// An all-dark stack (projector off, lens cap, wrong exposure) would decode to an empty frame
// that looks like "nothing in view": say what is wrong instead. `largest`: the largest white -
// black with `references`, else the brightest pixel of any image.
void refuse_dark_stack(const DecodeParams& params, const DecodeOptions& options, int largest, bool references) {
  if (references) {
    const float shadow_floor_dn = params.thresholds.shadow_min_contrast_dn;
    if (static_cast<float>(largest) < shadow_floor_dn) {
      throw_error(ErrorCode::kInvalidArgument,
                  "decode: all-dark stack: white - black is at most {} DN anywhere (shadow threshold {} DN); "
                  "is the projector on and the exposure right?",
                  largest, shadow_floor_dn);
    }
  } else if (static_cast<double>(largest) <
             options.black_level_dn + static_cast<double>(params.thresholds.shadow_min_contrast_dn)) {
    throw_error(ErrorCode::kInvalidArgument, "decode: all-dark stack: no pixel above {} DN", largest);
  }
}

// Images of `frame` left empty (DecodeOutputs) are not written.
void decode_cpu(const DecodeParams& params, const TriangulationParams& triangulation, const RayMap& rays,
                const std::vector<const std::uint16_t*>& planes, DecodedFrame* frame) {
  const int width = rays.width;
  const int height = rays.height;
  float* u = frame->projector_u.empty() ? nullptr : frame->projector_u.data();
  float* v = frame->projector_v.empty() ? nullptr : frame->projector_v.data();
  float* confidence = frame->confidence.data();
  std::uint8_t* mask = frame->mask.empty() ? nullptr : frame->mask.data();
  float* depth = frame->depth_m.data();
  const std::uint16_t* const* plane_pointers = planes.data();
  // Rows are independent; the per-pixel cost varies little (shadowed pixels stop early).
#if defined(_OPENMP)
#pragma omp parallel for schedule(static)
#endif
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t i = rays.index(x, y);
      const PlanePointerSamples samples{plane_pointers, i};
      PixelDecode pixel = decode_pixel(params, samples);
      depth[i] = triangulate_decoded_pixel(params.layout, triangulation, &pixel, rays.rays[i], rays.valid[i] != 0);
      confidence[i] = pixel.confidence;
      if (u == nullptr) continue;  // DecodeOutputs::kDepthAndConfidence
      u[i] = pixel.u;
      v[i] = pixel.v;
      mask[i] = pixel.mask;
    }
  }
}

}  // namespace

void DecodeOptions::validate() const {
  if (bit_depth < 1 || bit_depth > 16) {
    throw_error(ErrorCode::kInvalidArgument, "decode options: bit_depth {} outside 1..16", bit_depth);
  }
  require_finite_non_negative(saturation_dn, "saturation_dn");
  require_finite_non_negative(black_level_dn, "black_level_dn");
  require_finite_positive(gain_e_per_dn, "gain_e_per_dn");
  require_finite_non_negative(read_noise_dn, "read_noise_dn");
  require_finite_non_negative(shadow_min_contrast_dn, "shadow_min_contrast_dn");
  require_finite_non_negative(shadow_contrast_sigma, "shadow_contrast_sigma");
  require_finite_non_negative(gray_margin_sigma, "gray_margin_sigma");
  require_finite_non_negative(min_modulation_ratio, "min_modulation_ratio");
  require_finite_positive(max_phase_sigma_px, "max_phase_sigma_px");
  require_finite_non_negative(consistency_tolerance_px, "consistency_tolerance_px");
  require_finite_positive(confidence_sigma_px, "confidence_sigma_px");
  require_finite_positive(max_epipolar_error_px, "max_epipolar_error_px");
  if (!(min_triangulation_angle_deg >= 0.0 && min_triangulation_angle_deg < 90.0)) {
    throw_error(ErrorCode::kInvalidArgument, "decode options: min_triangulation_angle_deg {} outside [0, 90)",
                min_triangulation_angle_deg);
  }
  if (!(min_depth_m >= 0.0 && max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    throw_error(ErrorCode::kInvalidArgument, "decode options: depth range [{}, {}] m is empty or not finite",
                min_depth_m, max_depth_m);
  }
  if (newton_iterations < 1 || newton_iterations > 20) {
    throw_error(ErrorCode::kInvalidArgument, "decode options: newton_iterations {} outside 1..20",
                newton_iterations);
  }
}

std::size_t DecodedFrame::ok_count() const {
  return static_cast<std::size_t>(
      std::count(mask.data(), mask.data() + mask.pixel_count(), static_cast<std::uint8_t>(kDecodeOk)));
}

DecodeThresholds make_decode_thresholds(const DecodeOptions& o) {
  o.validate();
  DecodeThresholds t;
  const double top = std::ldexp(1.0, o.bit_depth) - 1.0;
  t.saturation_dn = static_cast<float>(o.saturation_dn > 0.0 ? o.saturation_dn : 0.98 * top);
  t.black_level_dn = static_cast<float>(o.black_level_dn);
  t.inverse_gain = static_cast<float>(1.0 / o.gain_e_per_dn);
  t.read_noise_variance = static_cast<float>(o.read_noise_dn * o.read_noise_dn + 1.0 / 12.0);
  t.shadow_min_contrast_dn =
      static_cast<float>(o.shadow_min_contrast_dn > 0.0 ? o.shadow_min_contrast_dn : std::ldexp(16.0, o.bit_depth - 12));
  t.shadow_contrast_sigma = static_cast<float>(o.shadow_contrast_sigma);
  t.gray_margin_sigma = static_cast<float>(o.gray_margin_sigma);
  t.min_modulation_ratio = static_cast<float>(o.min_modulation_ratio);
  t.max_phase_sigma_px = static_cast<float>(o.max_phase_sigma_px);
  t.consistency_tolerance_px = static_cast<float>(o.consistency_tolerance_px);
  t.confidence_sigma_px = static_cast<float>(o.confidence_sigma_px);
  return t;
}

TriangulationParams make_triangulation_params(const ScannerCalibration& calibration, const DecodeOptions& options) {
  options.validate();
  TriangulationParams p;
  p.projector = calibration.projector.cast<float>();
  const Pose T_projector_camera = calibration.T_camera_projector.inverse();
  p.T_projector_camera = to_rigid3f(T_projector_camera.to_rigid3d());
  const Eigen::Vector3d centre = calibration.T_camera_projector.translation();
  p.projector_centre_camera = {static_cast<float>(centre.x()), static_cast<float>(centre.y()),
                               static_cast<float>(centre.z())};
  p.min_sin_angle = static_cast<float>(std::sin(options.min_triangulation_angle_deg * kPi / 180.0));
  p.min_depth_m = static_cast<float>(options.min_depth_m);
  p.max_depth_m = static_cast<float>(options.max_depth_m);
  p.iterations = options.newton_iterations;
  p.max_epipolar_px = static_cast<float>(options.max_epipolar_error_px);
  return p;
}

struct Decoder::Impl {
  PatternSet set;
  ScannerCalibration calibration;
  Device device;
  DecodeOptions options;
  DecodeParams params;
  TriangulationParams triangulation;
  std::shared_ptr<const SharedRayMap> shared_rays;  // the camera's, shared with the other stages
  const RayMap* rays = nullptr;                     // shared_rays->host
  std::unique_ptr<detail::DecoderGpu> cuda;  // on a GPU: its state and pipeline
  bool decoded_on_device = false;  // the GPU holds an accepted stack's outputs (download_depth)
  StackCheckPlan check_plan;       // what the stack check judges (stack_check_shared.h)
};

Decoder::Decoder(const PatternSet& set, const ScannerCalibration& calibration, const Device& device,
                 const DecodeOptions& options, const GpuStream& stream, const GpuStream& upload_stream)
    : impl_(std::make_unique<Impl>()) {
  require_device(device);
  calibration.validate();
  impl_->set = set;
  impl_->calibration = calibration;
  impl_->device = device;
  impl_->options = options;
  impl_->params.layout = make_decode_layout(set);
  impl_->params.thresholds = make_decode_thresholds(options);
  impl_->check_plan = make_stack_check_plan(impl_->params);
  impl_->triangulation = make_triangulation_params(calibration, options);
  const bool columns = impl_->params.layout.axes[0].extent > 0;
  const int coded_extent = impl_->params.layout.axes[columns ? 0 : 1].extent;
  const int calibrated_extent = columns ? calibration.projector.width : calibration.projector.height;
  if (coded_extent != calibrated_extent) {
    throw_error(ErrorCode::kInvalidArgument,
                "pattern set '{}' codes {} projector {}, the calibration's projector has {}", set.name,
                coded_extent, columns ? "columns" : "rows", calibrated_extent);
  }
  impl_->shared_rays = shared_ray_map(calibration.camera, device);
  impl_->rays = &impl_->shared_rays->host;
  if (device.is_cuda()) {
    impl_->cuda = std::make_unique<detail::DecoderGpu>(
        impl_->params, impl_->triangulation, impl_->shared_rays, GpuStream::or_create(stream, device),
        GpuStream::or_create(upload_stream, device));
  }
}

void Decoder::download_depth(Image32f* depth_m) {
  if (!impl_->decoded_on_device) {
    if (impl_->device.is_cuda()) {
      throw_error(ErrorCode::kInvalidArgument, "download_depth: no stack decoded on the GPU");
    }
    return;  // a CPU decoder decodes into the frame
  }
  const int width = impl_->rays->width, height = impl_->rays->height;
  if (depth_m->width() != width || depth_m->height() != height) depth_m->resize(width, height);
  require_device(impl_->device);
  detail::DecodeOutputsHost host;
  host.depth = depth_m->data();
  impl_->cuda->download(host);
}

const Image32f* Decoder::depth_on_device() const {
  return impl_->cuda ? &impl_->cuda->depth_image() : nullptr;
}
const Image32f* Decoder::confidence_on_device() const {
  return impl_->cuda ? &impl_->cuda->confidence_image() : nullptr;
}

Decoder::~Decoder() = default;
Decoder::Decoder(Decoder&&) noexcept = default;
Decoder& Decoder::operator=(Decoder&&) noexcept = default;

const PatternSet& Decoder::pattern_set() const { return impl_->set; }
const DecodeOptions& Decoder::options() const { return impl_->options; }
const Device& Decoder::device() const { return impl_->device; }
const RayMap& Decoder::rays() const { return *impl_->rays; }
const DecodeParams& Decoder::decode_params() const { return impl_->params; }
const TriangulationParams& Decoder::triangulation_params() const { return impl_->triangulation; }

DecodedFrame Decoder::decode(const std::vector<Image16u>& stack) {
  DecodedFrame frame;
  decode(stack, DecodeOutputs::kAll, &frame);
  return frame;
}

bool Decoder::prefetch(const std::vector<Image16u>& stack) {
  if (!impl_->device.is_cuda() || stack.size() != impl_->set.size()) return false;
  for (const Image16u& image : stack) {
    if (image.width() != impl_->rays->width || image.height() != impl_->rays->height) return false;
  }
  require_device(impl_->device);  // this thread's current device
  std::vector<const std::uint16_t*> planes(stack.size());
  for (std::size_t k = 0; k < stack.size(); ++k) planes[k] = stack[k].data();
  return impl_->cuda->prefetch(planes.data());
}

void Decoder::decode(const std::vector<Image16u>& stack, DecodeOutputs outputs, DecodedFrame* frame_out) {
  const PatternSet& set = impl_->set;
  const int width = impl_->rays->width;
  const int height = impl_->rays->height;
  if (stack.size() != set.size()) {
    throw_error(ErrorCode::kInvalidArgument, "decode: {} images given, pattern set '{}' has {} patterns",
                stack.size(), set.name, set.size());
  }
  for (std::size_t k = 0; k < stack.size(); ++k) {
    const Image16u& image = stack[k];
    if (image.empty()) {
      throw_error(ErrorCode::kInvalidArgument, "decode: image {} ({}) is empty", k, pattern_label(set.patterns[k]));
    }
    if (image.width() != stack[0].width() || image.height() != stack[0].height()) {
      throw_error(ErrorCode::kInvalidArgument, "decode: image {} ({}) is {}x{}, image 0 is {}x{}", k,
                  pattern_label(set.patterns[k]), image.width(), image.height(), stack[0].width(),
                  stack[0].height());
    }
  }
  if (stack[0].width() != width || stack[0].height() != height) {
    throw_error(ErrorCode::kInvalidArgument, "decode: images are {}x{}, the calibrated camera is {}x{}",
                stack[0].width(), stack[0].height(), width, height);
  }
  const DecodeLayout& layout = impl_->params.layout;
  const bool references = layout.white_index >= 0 && layout.black_index >= 0;
  std::vector<const std::uint16_t*> planes(stack.size());
  for (std::size_t k = 0; k < stack.size(); ++k) planes[k] = stack[k].data();
  const bool all = outputs == DecodeOutputs::kAll;
  // Sized only once the stack is accepted (a refused stack leaves the frame as it was); reused
  // when already of the camera's size (resize() writes every pixel); emptied when not asked for.
  const auto size_outputs = [&] {
    DecodedFrame& frame = *frame_out;
    const auto size_to = [width, height](auto& image, bool wanted) {
      if (!wanted) {
        image = {};
      } else if (image.width() != width || image.height() != height) {
        image.resize(width, height);
      }
    };
    size_to(frame.projector_u, all);
    size_to(frame.projector_v, all);
    size_to(frame.confidence, true);
    size_to(frame.mask, all);
    size_to(frame.depth_m, true);
  };
  if (impl_->device.is_cuda()) {
    // The checks run where the stack lands, each grid pixel judged there into histograms; the
    // host takes their medians (judge_stack_histograms) while the GPU decodes. On the host the
    // same check took the frame's critical path 6 ms (docs/benchmarks.md).
    require_device(impl_->device);
    detail::DecoderGpu& cuda = *impl_->cuda;
    const bool on_device = outputs == DecodeOutputs::kDepthAndConfidenceOnDevice;
    impl_->decoded_on_device = false;
    int slot = cuda.take_prefetched(planes.data());
    if (slot < 0) slot = cuda.upload_async(planes.data());
    const StackCheckGrid grid =
        references && impl_->options.check_stack ? make_stack_check_grid(width, height, StackCheckLimits{}.max_samples)
                                                 : StackCheckGrid{};
    cuda.gather_check_async(slot, grid, impl_->check_plan);
    cuda.decode_slot(slot);
    if (!on_device) cuda.queue_landing(true, true);
    try {
      const detail::StackCheckInputs check = cuda.wait_check();
      refuse_dark_stack(impl_->params, impl_->options, check.largest, references);
      if (check.counts != nullptr) judge_stack_histograms(set, impl_->check_plan, check.lit, check.counts);
    } catch (...) {
      cuda.synchronize();  // the decode queued behind the check may still write the landing planes
      throw;
    }
    impl_->decoded_on_device = true;
    if (on_device) {
      cuda.synchronize();  // depth_on_device() is final when decode returns, as after a download
      return;
    }
    size_outputs();
    DecodedFrame& frame = *frame_out;
    detail::DecodeOutputsHost host;
    host.u = all ? frame.projector_u.data() : nullptr;
    host.v = all ? frame.projector_v.data() : nullptr;
    host.confidence = frame.confidence.data();
    host.mask = all ? frame.mask.data() : nullptr;
    host.depth = frame.depth_m.data();
    cuda.download(host);
    return;
  }
  int largest = std::numeric_limits<int>::min();
  if (references) {
    const std::uint16_t* white = planes[static_cast<std::size_t>(layout.white_index)];
    const std::uint16_t* black = planes[static_cast<std::size_t>(layout.black_index)];
    const auto count = static_cast<std::ptrdiff_t>(stack[0].pixel_count());
    // On all threads: 12 megapixels take ~10 ms on one, on every frame.
#if defined(_OPENMP)
#pragma omp parallel for schedule(static) reduction(max : largest)
#endif
    for (std::ptrdiff_t i = 0; i < count; ++i) largest = std::max(largest, int{white[i]} - int{black[i]});
  } else {
    for (const Image16u& image : stack) {
      largest = std::max(largest, int{*std::max_element(image.data(), image.data() + image.pixel_count())});
    }
  }
  refuse_dark_stack(impl_->params, impl_->options, largest, references);
  // One pattern image wrong everywhere (a stuck projector, images out of order) passes every
  // per-pixel test yet moves whole stripes: refused here with the image named.
  if (impl_->options.check_stack) check_stack_behaves(set, impl_->params, stack);
  size_outputs();
  decode_cpu(impl_->params, impl_->triangulation, *impl_->rays, planes, frame_out);
}

// --- Point clouds ----------------------------------------------------------------------

namespace {

Eigen::Vector3f point_at(const Image32f& depth, const RayMap& rays, int x, int y) {
  const Vec3f& r = rays.ray(x, y);
  const float z = depth(x, y);
  return {z * r.x, z * r.y, z * r.z};
}

// The difference along one image axis at (x, y): central when both neighbours are usable,
// one-sided when only one is; false when neither.
bool axis_difference(const Image32f& depth, const RayMap& rays, int x, int y, int dx, int dy, double max_jump_pixels,
                     Eigen::Vector3f* difference) {
  const float z = depth(x, y);
  const Vec3f& r = rays.ray(x, y);
  auto usable = [&](int nx, int ny) {
    if (nx < 0 || ny < 0 || nx >= depth.width() || ny >= depth.height()) return false;
    const float zn = depth(nx, ny);
    if (!(zn > 0.0f) || !rays.is_valid(nx, ny)) return false;
    // Pixel footprint: z times the angle between neighbouring rays (their z = 1).
    const Vec3f& rn = rays.ray(nx, ny);
    const double footprint =
        static_cast<double>(z) * std::hypot(static_cast<double>(rn.x - r.x), static_cast<double>(rn.y - r.y));
    return std::fabs(static_cast<double>(zn - z)) <= max_jump_pixels * footprint;
  };
  const bool forward = usable(x + dx, y + dy);
  const bool backward = usable(x - dx, y - dy);
  if (forward && backward) {
    *difference = point_at(depth, rays, x + dx, y + dy) - point_at(depth, rays, x - dx, y - dy);
  } else if (forward) {
    *difference = point_at(depth, rays, x + dx, y + dy) - point_at(depth, rays, x, y);
  } else if (backward) {
    *difference = point_at(depth, rays, x, y) - point_at(depth, rays, x - dx, y - dy);
  } else {
    return false;
  }
  return true;
}

}  // namespace

PointCloud depth_to_cloud(const Image32f& depth_m, const RayMap& rays, const Image32f* confidence,
                          const CloudOptions& options) {
  if (depth_m.width() != rays.width || depth_m.height() != rays.height) {
    throw_error(ErrorCode::kInvalidArgument, "depth_to_cloud: depth map {}x{}, ray map {}x{}", depth_m.width(),
                depth_m.height(), rays.width, rays.height);
  }
  if (confidence != nullptr &&
      (confidence->width() != depth_m.width() || confidence->height() != depth_m.height())) {
    throw_error(ErrorCode::kInvalidArgument, "depth_to_cloud: confidence {}x{}, depth map {}x{}",
                confidence->width(), confidence->height(), depth_m.width(), depth_m.height());
  }
  if (!(options.max_jump_pixels > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "depth_to_cloud: max_jump_pixels {} must be positive",
                options.max_jump_pixels);
  }
  PointCloud cloud;
  for (int y = 0; y < depth_m.height(); ++y) {
    for (int x = 0; x < depth_m.width(); ++x) {
      if (!(depth_m(x, y) > 0.0f) || !rays.is_valid(x, y)) continue;
      const float c = confidence != nullptr ? (*confidence)(x, y) : 1.0f;
      if (static_cast<double>(c) < options.min_confidence) continue;
      const Eigen::Vector3f point = point_at(depth_m, rays, x, y);
      Eigen::Vector3f horizontal, vertical;
      Eigen::Vector3f normal;
      bool has_normal = axis_difference(depth_m, rays, x, y, 1, 0, options.max_jump_pixels, &horizontal) &&
                        axis_difference(depth_m, rays, x, y, 0, 1, options.max_jump_pixels, &vertical);
      if (has_normal) {
        normal = horizontal.cross(vertical);
        const float length = normal.norm();
        has_normal = length > 0.0f && std::isfinite(length);
        if (has_normal) normal /= length;
      }
      if (!has_normal) {
        if (!options.keep_points_without_normal) continue;
        normal = -point.normalized();
      }
      if (normal.dot(point) > 0.0f) normal = -normal;  // face the camera
      cloud.positions.push_back(point);
      cloud.normals.push_back(normal);
      if (confidence != nullptr) cloud.confidence.push_back(c);
    }
  }
  return cloud;
}

PointCloud depth_to_cloud(const DecodedFrame& frame, const RayMap& rays, const CloudOptions& options) {
  return depth_to_cloud(frame.depth_m, rays, &frame.confidence, options);
}

}  // namespace sls
