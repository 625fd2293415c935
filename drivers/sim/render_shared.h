// Per-pixel image formation of the simulated structured-light scanner, one body of code for
// the CPU and CUDA renderers (DESIGN.md section 6).
//
// A frame is rendered in three steps:
//  1. trace_pixel(): once per frame and pixel — the camera ray (from the ray map, so lens
//     distortion is included) meets the scene; a shadow ray to the projector's centre decides
//     whether the point is lit; the point projects into the projector (with its distortion);
//     the camera and projector defocus blur at that depth and the irradiance per unit pattern
//     value (albedo, foreshortening, inverse-square falloff) are stored. This is also the
//     frame's ground truth (depth, projector coordinates, valid mask).
//  2. pattern_electrons(): per pattern image — the DMD pattern blurred by the projector lens
//     (an exact convolution, sls::pattern_value_blurred) times the stored irradiance, plus
//     ambient light: the mean photo-electrons at the pixel centre.
//  3. camera blur (defocus + pixel aperture, a Gaussian of the per-pixel sigma, applied as two
//     1-D gathers: exact for locally constant depth), then sensor_response(): shot noise,
//     read noise, gain, quantisation (drivers/sim/noise_shared.h), keyed by (seed, frame,
//     image, pixel) so the CPU and the GPU draw the same noise.
// Depth-only mode replaces 2-3 by depth_noise_sigma_m(): the depth error a phase-shifting
// decode would have at that pixel, from the same optics (see docs/simulator.md).
#pragma once

#include <cmath>
#include <cstdint>

#include "drivers/sim/noise_shared.h"
#include "drivers/sim/optics_shared.h"
#include "drivers/sim/scene_shared.h"
#include "sdk/core/camera_model_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"
#include "sdk/decode/pattern_shared.h"

namespace sls::sim {

// What the per-pixel code needs for one frame; plain data, passed to kernels by value.
// Geometry in double: ground truth must hold to well under a micrometre at 0.1 m range.
struct FrameRenderParams {
  SceneShapeT<double> scene;
  CameraIntrinsics projector;
  Rigid3d T_object_camera;     // camera frame -> object frame
  Rigid3d T_projector_object;  // object frame -> projector frame
  Vec3d projector_centre_object;
  SensorModel camera_sensor;
  LensModel camera_lens;
  ProjectorModel projector_optics;
  double cos_reference;        // foreshortening at which projector.white_electrons is defined
  double ambient_electrons;    // per unit albedo
  double shadow_offset_m;      // shadow rays start this far off the surface (self-hit guard)
  // The phase-shift part of the pattern set, for the depth-only noise model.
  int phase_period_px;
  int phase_steps;
  // What the decoder keeps (DecodeOptions' defaults), for the same model: a fringe weaker than
  // this share of (white − black)/2, a predicted coordinate noise above this (projector px)
  // or camera and projector rays meeting at less than this angle leave a pixel undecoded.
  double decode_min_modulation_ratio;
  double decode_max_phase_sigma_px;
  double decode_min_sin_angle;
};

enum PixelFlags : std::uint32_t {
  kPixelVisible = 1u,  // the camera ray meets the object
  kPixelLit = 2u,      // ... and the projector sees that point (not shadowed, inside its image)
  kPixelDecodable = 4u,  // ... and a phase-shift decode would keep it (depth-only mode)
};

// The per-frame geometry of one pixel (step 1).
struct PixelGeometry {
  float depth_m;               // camera-frame z of the visible point; 0 when not visible
  float projector_u;           // projector pixel coordinates of the point (when lit)
  float projector_v;
  float white_electrons;       // mean e- at pattern value 1 (full white), before ambient
  float ambient_electrons;     // mean e- from ambient light
  float camera_sigma_px;       // camera blur: defocus + pixel aperture
  float projector_sigma_u;     // projector blur along columns / rows, DMD pixels
  float projector_sigma_v;
  float depth_sigma_m;         // the depth noise of a phase-shift decode here (depth-only mode)
  std::uint32_t flags;         // PixelFlags
};

// Depth noise of an N-step phase-shift decode at a lit pixel, from the same optics:
//   modulation B = white/2 · (1 − black) · MTF_projector · MTF_camera (Gaussian MTFs of the
//   two blurs at the fringe period), intensity noise σ_I = sqrt(mean e⁻ + read²),
//   phase noise σ_φ = sqrt(2/N) σ_I / B, projector-coordinate noise σ_u = P σ_φ / 2π,
//   and depth noise σ_z = σ_u · (projector pixel footprint z_p / fx_p) / sin(angle between the
//   camera and projector rays). Grows with incidence (less light, smaller B) and defocus.
// `decodable`: the decoder's own tests pass (B / ((white − black)/2) = the MTF product at
// least decode_min_modulation_ratio, σ_u at most decode_max_phase_sigma_px, the angle at
// least the minimum): where they fail, a decode leaves the pixel empty, so must this model.
struct DepthNoise {
  double sigma_m = 0.0;
  bool decodable = false;
};

SLS_HOST_DEVICE inline DepthNoise depth_noise(const FrameRenderParams& p, const PixelGeometry& g,
                                              Vec3d camera_direction, Vec3d towards_projector,
                                              double projector_depth_m) {
  DepthNoise out;
  if (p.phase_steps <= 0 || p.phase_period_px <= 0) return out;
  const double period = static_cast<double>(p.phase_period_px);
  const double black = p.projector_optics.contrast_ratio > 1.0 ? 1.0 / p.projector_optics.contrast_ratio : 0.0;
  const double projector_pixel_m = projector_depth_m / p.projector.fx;
  const double camera_pixel_m = static_cast<double>(g.depth_m) * p.camera_sensor.pixel_pitch_m /
                                lens_image_distance_m(p.camera_lens, p.camera_lens.focus_distance_m);
  const double period_camera_px = period * projector_pixel_m / camera_pixel_m;
  const double mtf = gaussian_mtf(static_cast<double>(g.projector_sigma_u), period) *
                     gaussian_mtf(static_cast<double>(g.camera_sigma_px), period_camera_px);
  const double white = static_cast<double>(g.white_electrons);
  const double modulation = 0.5 * white * (1.0 - black) * mtf;
  const double mean = static_cast<double>(g.ambient_electrons) + 0.5 * white;
  const double read = p.camera_sensor.read_noise_e;
  if (!(modulation > 0.0)) {  // no fringe left: any depth is as good as another
    out.sigma_m = 1.0;
    return out;
  }
  const double sigma_phase = std::sqrt(2.0 / p.phase_steps) * std::sqrt(mean + read * read) / modulation;
  const double sigma_u = period * sigma_phase / 6.283185307179586;
  const double cos_angle = -dot(camera_direction, towards_projector);
  const double sin_angle = std::sqrt(1.0 - (cos_angle > 1.0 ? 1.0 : cos_angle * cos_angle));
  out.sigma_m = sigma_u * projector_pixel_m / (sin_angle > 1e-3 ? sin_angle : 1e-3);
  out.decodable = mtf >= p.decode_min_modulation_ratio && sigma_u <= p.decode_max_phase_sigma_px &&
                  sin_angle >= p.decode_min_sin_angle;
  return out;
}

SLS_HOST_DEVICE inline PixelGeometry trace_pixel(const FrameRenderParams& p, Vec3f ray_camera, bool ray_valid) {
  PixelGeometry g{};
  if (!ray_valid) return g;
  const Vec3d d_camera{static_cast<double>(ray_camera.x), static_cast<double>(ray_camera.y),
                       static_cast<double>(ray_camera.z)};
  const double length = norm(d_camera);
  RayT<double> ray;
  ray.origin = p.T_object_camera.translation;
  ray.direction = (1.0 / length) * rotate_vector(p.T_object_camera, d_camera);
  HitT<double> hit;
  if (!intersect(p.scene, ray, 0.0, 10.0, &hit)) return g;
  // Depth along the optical axis: the hit is at t along a unit ray whose camera z is 1/length.
  const double depth = hit.t / length;
  g.depth_m = static_cast<float>(depth);
  g.flags = kPixelVisible;
  g.camera_sigma_px = static_cast<float>(defocus_sigma_px(p.camera_lens, p.camera_sensor, depth));
  g.ambient_electrons = static_cast<float>(p.ambient_electrons * hit.albedo);

  // Lit: the projector's centre is in front of the surface and nothing lies between them.
  const Vec3d to_projector = p.projector_centre_object - hit.point;
  const double distance = norm(to_projector);
  const Vec3d towards = (1.0 / distance) * to_projector;
  const double cos_incidence = dot(hit.normal, towards);
  if (!(cos_incidence > 0.0)) return g;
  RayT<double> shadow;
  shadow.origin = hit.point + p.shadow_offset_m * hit.normal;
  shadow.direction = towards;
  HitT<double> blocker;
  if (intersect(p.scene, shadow, 0.0, distance, &blocker)) return g;

  const Vec3d point_projector = transform_point(p.T_projector_object, hit.point);
  Vec2d projector_pixel;
  if (!project(p.projector, point_projector, &projector_pixel)) return g;
  if (!(projector_pixel.x >= -0.5 && projector_pixel.x < p.projector.width - 0.5 && projector_pixel.y >= -0.5 &&
        projector_pixel.y < p.projector.height - 0.5)) {
    return g;
  }
  // Irradiance: Lambertian reflection of the projector's light, which falls off with the
  // square of the distance from its lens (normalised at its focus distance) and with the
  // cosine of incidence (normalised to the reference geometry of white_electrons).
  const double falloff = (p.projector_optics.lens.focus_distance_m * p.projector_optics.lens.focus_distance_m) /
                         (point_projector.z * point_projector.z);
  g.white_electrons = static_cast<float>(p.projector_optics.white_electrons * hit.albedo * falloff *
                                         (cos_incidence / p.cos_reference));
  g.projector_u = static_cast<float>(projector_pixel.x);
  g.projector_v = static_cast<float>(projector_pixel.y);
  const Vec2d projector_sigma = projector_blur_sigma_px(p.projector_optics, point_projector.z);
  g.projector_sigma_u = static_cast<float>(projector_sigma.x);
  g.projector_sigma_v = static_cast<float>(projector_sigma.y);
  g.flags |= kPixelLit;
  const DepthNoise noise = depth_noise(p, g, ray.direction, towards, point_projector.z);
  g.depth_sigma_m = static_cast<float>(noise.sigma_m);
  if (noise.decodable) g.flags |= kPixelDecodable;
  return g;
}

// Step 2: mean photo-electrons at a pixel centre for one projected pattern.
SLS_HOST_DEVICE inline float pattern_electrons(const PixelGeometry& g, const PatternDesc& pattern,
                                               const ProjectorModel& projector) {
  if (!(g.flags & kPixelVisible)) return 0.0f;
  if (!(g.flags & kPixelLit)) return g.ambient_electrons;
  const bool columns = pattern.axis == PatternAxis::kColumns;
  const double u = columns ? static_cast<double>(g.projector_u) : static_cast<double>(g.projector_v);
  const double sigma = columns ? static_cast<double>(g.projector_sigma_u)
                               : static_cast<double>(g.projector_sigma_v);
  const double value = pattern_value_blurred(pattern, u, sigma);
  return static_cast<float>(static_cast<double>(g.ambient_electrons) +
                            static_cast<double>(g.white_electrons) * projector_relative_irradiance(projector, value));
}

// Step 3a: one 1-D pass of the camera blur at pixel `i` of a line of `n` samples (stride in
// elements), with the output pixel's sigma. Radius capped at kMaxBlurRadius (a 3-sigma
// kernel up to sigma = 8 px: beyond that a surface is outside any usable depth of field).
constexpr int kMaxBlurRadius = 24;

SLS_HOST_DEVICE inline float blur_gather_1d(const float* line, int n, int stride, int i, float sigma) {
  if (!(sigma > 0.05f)) return line[i * stride];
  int radius = static_cast<int>(std::ceil(3.0f * sigma));
  if (radius > kMaxBlurRadius) radius = kMaxBlurRadius;
  // Double arithmetic, rounded once to float: glibc's and CUDA's float exp differ in the last
  // bit, and the shot-noise sampler (rejection sampling between 10 and 1000 e-) turns a
  // last-bit difference of the mean into a different draw. Rounded from double, the CPU and
  // GPU means agree except when they straddle a float rounding boundary (odds ~1e-8).
  const double inverse_two_variance = 0.5 / (static_cast<double>(sigma) * static_cast<double>(sigma));
  double sum = 0.0, weights = 0.0;
  for (int k = -radius; k <= radius; ++k) {
    const int j = i + k;
    if (j < 0 || j >= n) continue;  // the image edge: renormalise over what exists
    const double w = std::exp(-static_cast<double>(k * k) * inverse_two_variance);
    sum += w * static_cast<double>(line[j * stride]);
    weights += w;
  }
  return static_cast<float>(sum / weights);
}

// Step 3b: the digital number.
SLS_HOST_DEVICE inline std::uint16_t pixel_digital_number(const SensorModel& sensor, float electrons,
                                                          const NoiseKey& key, bool noise) {
  const int dn = noise ? sensor_response(sensor, static_cast<double>(electrons), key)
                       : sensor_response_noiseless(sensor, static_cast<double>(electrons));
  return static_cast<std::uint16_t>(dn);
}

}  // namespace sls::sim
