// Per-pixel image formation of the simulated structured-light scanner, one body of code for
// the CPU and CUDA renderers (DESIGN.md section 6).
//
// A frame is rendered in three steps:
//  1. trace_pixel(): once per frame and pixel — the camera ray (from the ray map, so lens
//     distortion is included) meets the scene; a shadow ray to the projector's centre decides
//     whether the point is lit; the point projects into the projector (with its distortion);
//     the camera and projector defocus blur at that depth and the irradiance per unit pattern
//     value (albedo, foreshortening, inverse-square falloff) are stored. This is also the
//     frame's ground truth (depth, projector coordinates, valid mask). A varying albedo is
//     integrated over the pixel's footprint (see "The pixel's footprint" below).
//  2. pattern_electrons(): per pattern image — the DMD pattern blurred by the projector lens
//     (an exact convolution, sls::pattern_value_blurred) times the stored irradiance, plus
//     ambient light: the mean photo-electrons at the pixel centre.
//  3. camera blur (defocus + pixel aperture, a Gaussian of the per-pixel sigma, applied as two
//     1-D gathers: exact for locally constant depth; the lens alone where the pixel's area is
//     integrated in step 1), then sensor_response(): shot noise,
//     read noise, gain, quantisation (drivers/sim/noise_shared.h), keyed by (seed, frame,
//     image, pixel) so the CPU and the GPU draw the same noise.
// Depth-only mode replaces 2-3 by depth_noise_sigma_m(): the depth error a phase-shifting
// decode would have at that pixel, from the same optics (see docs/simulator.md).
#pragma once

#include <cmath>
#include <cstdint>

#include "drivers/sim/albedo_footprint_shared.h"
#include "drivers/sim/material_shared.h"
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
  CameraIntrinsics camera;     // the model of the ray map: sub-pixel rays (pixel_footprint)
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
  double phase_period_px;  // may be fractional (pattern_shared.h)
  int phase_steps;
  // What the decoder keeps (DecodeOptions' defaults), for the same model: a fringe weaker than
  // this share of (white − black)/2, a predicted coordinate noise above this (projector px)
  // or camera and projector rays meeting at less than this angle leave a pixel undecoded.
  double decode_min_modulation_ratio;
  double decode_max_phase_sigma_px;
  double decode_min_sin_angle;
  SurfaceMaterial material;    // the object's finish (material_shared.h); default: Lambertian
};

enum PixelFlags : std::uint32_t {
  kPixelVisible = 1u,  // the camera ray meets the object
  kPixelLit = 2u,      // ... and the projector sees that point (not shadowed, inside its image)
  kPixelDecodable = 4u,  // ... and a phase-shift decode would keep it (depth-only mode)
};

// The per-frame geometry of one pixel (step 1).
struct PixelGeometry {
  float depth_m;               // camera-frame z of the visible point; 0 when not visible
  float projector_u;           // projector pixel coordinates of the point (when lit): ground truth
  float projector_v;
  float pattern_u;             // where the pattern is read for this pixel (projector pixels):
  float pattern_v;             // projector_u/v, or the albedo-weighted centroid of the footprint
  float white_electrons;       // mean e- at pattern value 1 (full white), before ambient
  float ambient_electrons;     // mean e- from ambient light
  float camera_sigma_px;       // camera blur: lens (defocus, diffraction) + pixel aperture, or
                               // the lens alone where the pixel's area is integrated
  float projector_sigma_u;     // pattern blur along columns / rows, DMD pixels: the projector
  float projector_sigma_v;     // lens (+ the pixel aperture where the pixel is integrated)
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
  if (p.phase_steps <= 0 || !(p.phase_period_px > 0.0)) return out;
  const double period = p.phase_period_px;
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

// ---------------------------------------------------------------------------------------
// The pixel's footprint. A camera pixel integrates the irradiance over its area. Where the
// albedo varies (albedo_varies(): the chessboard's squares, a solid texture) the albedo at
// the centre ray alone would put every albedo edge on the pixel grid, up to ±0.5 px from
// where it projects (0.13 px RMS in the corners of a simulated calibration capture). So
// there the albedo is averaged over the footprint: the pixel square mapped onto the plane
// tangent to the surface at the centre hit through sub-pixel rays. A point δ (pixels) from the
// centre sees the normalised ray n + A δ, A = dn/dpixel = (diag(fx, fy) · J_distortion(n))⁻¹:
// the camera model of the ray map (sdk/core/camera_model_shared.h) linearised over the pixel;
// the linearisation's error, of order k1 |n| δ², is below 1e-5 px for the rig's lens. Geometry
// (depth, projector coordinates, shadow) stays the centre ray's.
//   Chessboard: the exact area integral over the footprint quadrilateral
//     (chessboard_mean_albedo()). A sampled average converges only as 1/N: an edge along a
//     row of an N x N grid of samples jumps in steps of 1/N pixel (measured: up to 0.13 px
//     at N = 4, 0.06 px at N = 8), and the board's edges run close to the image axes.
//   Solid texture (smooth): the midpoint rule on kTextureSamplesPerAxis² sub-pixel points.
// The pattern is then read at the footprint's albedo-weighted centroid (where the pixel's
// light comes from on average) and blurred by the pixel's aperture mapped into the projector
// (the box's variance, 1/12 px², through the footprint's projector Jacobian), and the camera
// blur is the lens alone: each image gets the pixel's aperture once (docs/simulator.md).
// Uniform albedo: the point sample at the centre, the pattern there, the aperture in the
// camera blur, as before.

// Sub-pixel samples per axis for a smooth solid texture (AlbedoT). The midpoint rule's error
// falls as 1/N²: for the textures in use (period ≥ 1 mm, pixels of 37.5 µm seen at up to 73°
// from the normal) it is 4e-4 of the albedo at N = 4 (about 1 DN at full white), 1e-4 at
// N = 8 (Renderer.FootprintAlbedoConvergesWithTheSamples).
constexpr int kTextureSamplesPerAxis = 8;

struct PixelFootprint {
  Vec3d origin;        // the camera centre, object frame
  Vec3d ray;           // object-frame ray of the pixel centre (camera z = 1)
  Vec3d ray_per_px_x;  // its change per pixel along the image x and y axes
  Vec3d ray_per_px_y;
  Vec3d normal;        // the tangent plane at the centre hit: dot(x − origin, normal) = offset
  double offset;
};

SLS_HOST_DEVICE inline PixelFootprint pixel_footprint(const FrameRenderParams& p, Vec3d ray_camera,
                                                      const HitT<double>& hit) {
  const Vec2d n{ray_camera.x / ray_camera.z, ray_camera.y / ray_camera.z};
  double j[4];
  distortion_jacobian(p.camera, n, j);
  // d pixel / d n = diag(fx, fy) J; its inverse's columns are dn/dx and dn/dy.
  const double m00 = p.camera.fx * j[0], m01 = p.camera.fx * j[1];
  const double m10 = p.camera.fy * j[2], m11 = p.camera.fy * j[3];
  const double inverse_det = 1.0 / (m00 * m11 - m01 * m10);
  PixelFootprint f;
  f.origin = p.T_object_camera.translation;
  f.ray = rotate_vector(p.T_object_camera, Vec3d{n.x, n.y, 1.0});
  f.ray_per_px_x = rotate_vector(p.T_object_camera, Vec3d{m11 * inverse_det, -m10 * inverse_det, 0.0});
  f.ray_per_px_y = rotate_vector(p.T_object_camera, Vec3d{-m01 * inverse_det, m00 * inverse_det, 0.0});
  f.normal = hit.normal;
  f.offset = dot(hit.point - f.origin, hit.normal);
  return f;
}

// Where the ray (dx, dy) pixels from the centre meets the tangent plane; false when it
// misses (grazing view, or the plane behind the camera).
SLS_HOST_DEVICE inline bool footprint_point(const PixelFootprint& f, double dx, double dy, Vec3d* point) {
  const Vec3d d = f.ray + dx * f.ray_per_px_x + dy * f.ray_per_px_y;
  const double depth = f.offset / dot(d, f.normal);  // camera z of the point
  if (!(depth > 0.0 && depth < 10.0)) return false;
  *point = f.origin + depth * d;
  return true;
}

struct FootprintAlbedo {
  double albedo = 0.0;  // mean over the footprint
  Vec3d centroid{0.0, 0.0, 0.0};  // albedo-weighted, object frame
  Vec3d corner[4];      // the pixel's corners (−½,−½), (½,−½), (½,½), (−½,½) on the plane
};

// The albedo over the pixel's footprint (see above); false where the footprint is not
// bounded (grazing view) or too large (chessboard_mean_albedo()): the caller point-samples.
// N: sub-pixel samples per axis of a solid texture (a parameter for the convergence test).
template <int N = kTextureSamplesPerAxis>
SLS_HOST_DEVICE inline bool footprint_albedo(const SceneShapeT<double>& scene, const PixelFootprint& f,
                                             FootprintAlbedo* out) {
  const double corner_x[4] = {-0.5, 0.5, 0.5, -0.5};
  const double corner_y[4] = {-0.5, -0.5, 0.5, 0.5};
  for (int k = 0; k < 4; ++k) {
    if (!footprint_point(f, corner_x[k], corner_y[k], &out->corner[k])) return false;
  }
  if (scene.kind == SceneKind::kChessboard) {
    // The sheet z = 0 is its own tangent plane.
    const Vec2d quad[4] = {{out->corner[0].x, out->corner[0].y},
                           {out->corner[1].x, out->corner[1].y},
                           {out->corner[2].x, out->corner[2].y},
                           {out->corner[3].x, out->corner[3].y}};
    Vec2d centroid{0.0, 0.0};
    if (!chessboard_mean_albedo(scene.chessboard, quad, &out->albedo, &centroid)) return false;
    out->centroid = {centroid.x, centroid.y, 0.0};
    return true;
  }
  constexpr int n = N;
  double sum = 0.0;
  Vec3d weighted{0.0, 0.0, 0.0}, mean_point{0.0, 0.0, 0.0};
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      Vec3d point;
      if (!footprint_point(f, (i + 0.5) / n - 0.5, (j + 0.5) / n - 0.5, &point)) return false;
      const double albedo = surface_albedo(scene, point);
      sum += albedo;
      weighted = weighted + albedo * point;
      mean_point = mean_point + (1.0 / (n * n)) * point;
    }
  }
  out->albedo = sum / (n * n);
  out->centroid = sum > 0.0 ? (1.0 / sum) * weighted : mean_point;
  return true;
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
  // The camera blur with the pixel's aperture: a point sample's (see the footprint above).
  const double point_sampled_sigma_px = defocus_sigma_px(p.camera_lens, p.camera_sensor, depth);
  g.camera_sigma_px = static_cast<float>(point_sampled_sigma_px);
  double albedo = hit.albedo;
  FootprintAlbedo footprint;
  const bool integrated = albedo_varies(p.scene) && footprint_albedo(p.scene, pixel_footprint(p, d_camera, hit),
                                                                     &footprint);
  if (integrated) {
    albedo = footprint.albedo;
    g.camera_sigma_px = static_cast<float>(lens_blur_sigma_px(p.camera_lens, p.camera_sensor, depth));
  }
  g.ambient_electrons = static_cast<float>(p.ambient_electrons * p.material.diffuse_scale * albedo);

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
  // Irradiance: the projector's light, which falls off with the square of the distance from
  // its lens (normalised at its focus distance) and with the cosine of incidence (normalised
  // to the reference geometry of white_electrons), reflected by the material (Lambertian:
  // the albedo; metal: plus its specular lobe, material_shared.h).
  const double falloff = (p.projector_optics.lens.focus_distance_m * p.projector_optics.lens.focus_distance_m) /
                         (point_projector.z * point_projector.z);
  const double reflectance = material_reflectance(p.material, albedo, hit.normal, towards, -ray.direction);
  g.white_electrons = static_cast<float>(p.projector_optics.white_electrons * reflectance * falloff *
                                         (cos_incidence / p.cos_reference));
  g.projector_u = static_cast<float>(projector_pixel.x);
  g.projector_v = static_cast<float>(projector_pixel.y);
  g.pattern_u = g.projector_u;
  g.pattern_v = g.projector_v;
  const Vec2d projector_sigma = projector_blur_sigma_px(p.projector_optics, point_projector.z);
  g.projector_sigma_u = static_cast<float>(projector_sigma.x);
  g.projector_sigma_v = static_cast<float>(projector_sigma.y);
  g.flags |= kPixelLit;
  // The depth-noise model takes the blurs of a point sample (the pixel's aperture in the
  // camera's blur); an integrated pixel has the same blur, split differently (below).
  PixelGeometry model = g;
  model.camera_sigma_px = static_cast<float>(point_sampled_sigma_px);
  const DepthNoise noise = depth_noise(p, model, ray.direction, towards, point_projector.z);
  g.depth_sigma_m = static_cast<float>(noise.sigma_m);
  if (noise.decodable) g.flags |= kPixelDecodable;

  if (integrated) {
    // The pattern where the pixel's light comes from, blurred by the pixel's aperture mapped
    // into the projector: the variance of u over the pixel, (du/dx² + du/dy²) / 12.
    Vec2d corner[4], centroid;
    bool projected = project(p.projector, transform_point(p.T_projector_object, footprint.centroid), &centroid);
    for (int k = 0; k < 4; ++k) {
      projected = projected && project(p.projector, transform_point(p.T_projector_object, footprint.corner[k]),
                                       &corner[k]);
    }
    if (projected) {
      const double du_dx = 0.5 * ((corner[1].x + corner[2].x) - (corner[0].x + corner[3].x));
      const double du_dy = 0.5 * ((corner[2].x + corner[3].x) - (corner[0].x + corner[1].x));
      const double dv_dx = 0.5 * ((corner[1].y + corner[2].y) - (corner[0].y + corner[3].y));
      const double dv_dy = 0.5 * ((corner[2].y + corner[3].y) - (corner[0].y + corner[1].y));
      g.pattern_u = static_cast<float>(centroid.x);
      g.pattern_v = static_cast<float>(centroid.y);
      g.projector_sigma_u = static_cast<float>(std::sqrt(
          projector_sigma.x * projector_sigma.x + (du_dx * du_dx + du_dy * du_dy) * kPixelApertureVariancePx2));
      g.projector_sigma_v = static_cast<float>(std::sqrt(
          projector_sigma.y * projector_sigma.y + (dv_dx * dv_dx + dv_dy * dv_dy) * kPixelApertureVariancePx2));
    } else {
      g.camera_sigma_px = static_cast<float>(point_sampled_sigma_px);  // the aperture in the camera blur
    }
  }
  return g;
}

// Step 2: mean photo-electrons at a pixel centre for one projected pattern.
// `levels` is the PatternDesc itself or a PatternLevelTable of it: the same value, the table
// sparing a cos per level of a phase pattern (the CPU renderer makes one per image).
template <typename Levels>
SLS_HOST_DEVICE inline float pattern_electrons(const PixelGeometry& g, const Levels& levels, PatternAxis axis,
                                               const ProjectorModel& projector) {
  if (!(g.flags & kPixelVisible)) return 0.0f;
  if (!(g.flags & kPixelLit)) return g.ambient_electrons;
  const bool columns = axis == PatternAxis::kColumns;
  const double u = columns ? static_cast<double>(g.pattern_u) : static_cast<double>(g.pattern_v);
  const double sigma = columns ? static_cast<double>(g.projector_sigma_u)
                               : static_cast<double>(g.projector_sigma_v);
  const double value = projector.gamma == 1.0
                           ? pattern_value_blurred(levels, u, sigma)
                           : pattern_value_blurred(levels, u, sigma, ProjectorGammaResponse{projector.gamma});
  return static_cast<float>(static_cast<double>(g.ambient_electrons) +
                            static_cast<double>(g.white_electrons) * projector_relative_irradiance(projector, value));
}

SLS_HOST_DEVICE inline float pattern_electrons(const PixelGeometry& g, const PatternDesc& pattern,
                                               const ProjectorModel& projector) {
  return pattern_electrons(g, pattern, pattern.axis, projector);
}

// Step 3a: one 1-D pass of the camera blur at pixel `i` of a line of `n` samples (stride in
// elements), with the output pixel's sigma. Radius capped at kMaxBlurRadius (a 3-sigma
// kernel up to sigma = 8 px: beyond that a surface is outside any usable depth of field).
constexpr int kMaxBlurRadius = 24;

// The taps of the blur at a pixel of blur sigma `sigma`: 0 for none (a sigma of at most 0.05 px).
SLS_HOST_DEVICE inline int blur_radius(float sigma) {
  if (!(sigma > 0.05f)) return 0;
  const int radius = static_cast<int>(std::ceil(3.0f * sigma));
  return radius > kMaxBlurRadius ? kMaxBlurRadius : radius;
}

// The weights w_k = exp(-k^2 a), a = 1 / (2 sigma^2), by recurrence: w_k = w_{k-1} q_k with
// q_k = q_{k-1} exp(-2a), from q_1 = exp(-a): two exps a pixel, not one a tap (a third of a CPU
// render), a few ulps of double off. The same for every image of a frame (sigma is the
// pixel's), so the CPU renderer makes them once a frame.
struct BlurRecurrence {
  double q_first = 0.0;  // exp(-a)
  double q_step = 0.0;   // exp(-2a)
};

SLS_HOST_DEVICE inline BlurRecurrence blur_recurrence(float sigma) {
  const double a = 0.5 / (static_cast<double>(sigma) * static_cast<double>(sigma));
  return {std::exp(-a), std::exp(-2.0 * a)};
}

// Double arithmetic, rounded once to float: glibc's and CUDA's float exp differ in the last
// bit, and the shot-noise sampler (rejection sampling between 10 and 1000 e-) turns a last-bit
// difference of the mean into a different draw. Rounded from double, the CPU and GPU means
// agree except when they straddle a float rounding boundary (odds ~1e-8).
SLS_HOST_DEVICE inline float blur_gather_1d(const float* line, int n, int stride, int i, int radius,
                                            const BlurRecurrence& recurrence) {
  if (radius == 0) return line[i * stride];
  const double q_step = recurrence.q_step;
  double q = recurrence.q_first, w = 1.0;
  double sum = static_cast<double>(line[i * stride]), weights = 1.0;
  for (int k = 1; k <= radius; ++k) {
    w *= q;
    q *= q_step;
    // The image edge: renormalise over what exists.
    if (i - k >= 0) {
      sum += w * static_cast<double>(line[(i - k) * stride]);
      weights += w;
    }
    if (i + k < n) {
      sum += w * static_cast<double>(line[(i + k) * stride]);
      weights += w;
    }
  }
  return static_cast<float>(sum / weights);
}

SLS_HOST_DEVICE inline float blur_gather_1d(const float* line, int n, int stride, int i, float sigma) {
  const int radius = blur_radius(sigma);
  return radius == 0 ? line[i * stride] : blur_gather_1d(line, n, stride, i, radius, blur_recurrence(sigma));
}

// Step 3b: the digital number.
SLS_HOST_DEVICE inline std::uint16_t pixel_digital_number(const SensorModel& sensor, float electrons,
                                                          const NoiseKey& key, bool noise) {
  const int dn = noise ? sensor_response(sensor, static_cast<double>(electrons), key)
                       : sensor_response_noiseless(sensor, static_cast<double>(electrons));
  return static_cast<std::uint16_t>(dn);
}

}  // namespace sls::sim
