// Optics of the simulated rig, shared by the CPU and CUDA renderers (DESIGN.md section 6):
// the camera sensor, thin-lens defocus blur of the camera and the projector, and the default
// rig whose numbers (and their basis) are written up in docs/simulator-optics.md. Change a
// default only together with that document, with a note saying why.
//
// Units: metres, electrons (e-), digital numbers (DN). "Depth" is the distance from the
// (thin) lens along its optical axis, i.e. the camera- or projector-frame z.
//
// Blur model. A thin lens of focal length f and aperture diameter A = f/N, focused at object
// distance s_f (sensor at v_f = f s_f / (s_f - f)), images a point at distance s into a
// uniform disk (circle of confusion) of diameter on the sensor
//     c = A |v_f - v| / v = A f |s - s_f| / (s (s_f - f)).
// It is replaced by a Gaussian with the same per-axis second moment, sigma = c/4 (a uniform
// disk of radius R has per-axis variance R^2/4). Its MTF then drops to 0.54 where the disk's
// falls to 0.50, whereas the often quoted c/(2*sqrt(2)) (the 2D rms radius) gives 0.29 there:
// c/4 is the better match for the fringe contrast that matters here. Diffraction adds, in
// quadrature, the Gaussian fit of the Airy core, sigma = 0.42 lambda N_w with the working
// f-number N_w = N (1 + m), m = v_f / s_f; aberrations add `residual_sigma_m`.
#pragma once

#include <cmath>

#include "sdk/core/camera_model_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::sim {

struct SensorModel {
  int width = 0;                   // pixels
  int height = 0;
  double pixel_pitch_m = 0;
  double full_well_e = 0;          // saturation capacity: the photodiode holds no more
  double read_noise_e = 0;         // temporal dark noise, rms e-
  double quantum_efficiency = 0;   // e- per photon; for exposure estimates (the renderer works in e-)
  int bit_depth = 12;              // ADC bits; DN are clamped to 0 .. 2^bit_depth - 1
  double gain_e_per_dn = 1;        // system gain 1/K: electrons per DN
  double black_level_dn = 0;       // offset added before quantisation, keeps the noise floor unclipped
  double gamma = 1;                // DN above black = range * (x / range)^gamma; 1 = linear (machine vision)
};

struct LensModel {
  double focal_length_m = 0;
  double f_number = 0;             // N = f / A, the f-number on the barrel (infinity focus)
  double focus_distance_m = 0;     // object side: lens to the plane in focus
  double wavelength_m = 550e-9;    // for the diffraction floor
  double residual_sigma_m = 0;     // aberrations at best focus, image-side sigma (0: diffraction limited)
};

// The projector: a DMD imaged by a lens onto the scene. Its "sensor" is the DMD, so the same
// thin-lens formulas give the blur in DMD pixels of a pattern landing at a given depth.
struct ProjectorModel {
  int width = 0;                   // DMD columns
  int height = 0;                  // DMD rows
  double pixel_pitch_x_m = 0;      // column pitch on the DMD
  double pixel_pitch_y_m = 0;      // row pitch (half the column pitch on the diamond DLP4500)
  LensModel lens;
  double contrast_ratio = 0;       // full-on / full-off; <= 1 means no black level
  // Light emitted for DMD level L: 255 (L / 255)^gamma. 1: linear, as a DLP in pattern mode
  // (bit planes weighted by time); a projector fed video applies its display gamma (~2.2).
  double gamma = 1.0;
  // Exposure scale: mean e- one camera pixel collects from full white (level 255) on a white
  // Lambertian target (albedo 1) at the focus distance, facing the camera. The renderer scales
  // it by albedo, foreshortening and projector_relative_irradiance().
  double white_electrons = 0;
};

struct RigOptics {
  SensorModel camera_sensor;
  LensModel camera_lens;
  ProjectorModel projector;
  double working_distance_m = 0;       // camera lens to the plane in focus (= camera_lens.focus_distance_m)
  double triangulation_angle_rad = 0;  // between the camera and projector optical axes
  double baseline_m = 0;               // between the two lens centres
  double ambient_electrons = 0;        // e- per camera pixel per exposure from room light, same target
};

struct DepthOfField {
  double near_m = 0;
  double far_m = 0;  // HUGE_VAL when the blur never reaches the limit behind the focus
};

// --- Thin lens -------------------------------------------------------------------------

// Image distance v of an object at distance s: 1/f = 1/s + 1/v (negative: virtual image).
SLS_HOST_DEVICE inline double lens_image_distance_m(const LensModel& lens, double object_distance_m) {
  return lens.focal_length_m * object_distance_m / (object_distance_m - lens.focal_length_m);
}

// Lateral magnification at the focus distance, image size / object size = v_f / s_f.
SLS_HOST_DEVICE inline double lens_magnification(const LensModel& lens) {
  return lens.focal_length_m / (lens.focus_distance_m - lens.focal_length_m);
}

// The f-number seen from the image side at the focus distance, N (1 + m): what sets
// diffraction and image-side depth of focus in close-up work.
SLS_HOST_DEVICE inline double working_f_number(const LensModel& lens) {
  return lens.f_number * (1.0 + lens_magnification(lens));
}

// Diameter (m, image side) of the blur disk of a point at `object_distance_m`; 0 at the focus
// distance. HUGE_VAL for points at or behind the lens, or a lens focused inside its focal length.
SLS_HOST_DEVICE inline double circle_of_confusion_m(const LensModel& lens, double object_distance_m) {
  const double f = lens.focal_length_m;
  const double s_f = lens.focus_distance_m;
  if (!(object_distance_m > 0.0) || !(s_f > f) || !(f > 0.0) || !(lens.f_number > 0.0)) return HUGE_VAL;
  const double aperture = f / lens.f_number;
  return aperture * f * std::fabs(object_distance_m - s_f) / (object_distance_m * (s_f - f));
}

// Gaussian sigma with the same per-axis variance as a uniform disk of diameter c.
SLS_HOST_DEVICE inline double blur_circle_to_sigma(double diameter) { return 0.25 * diameter; }

// Gaussian fit of the Airy core (Zhang, Zerubia, Olivo-Marin 2007: sigma = 0.21 lambda / NA,
// NA = 1 / (2 N_w)), image side.
SLS_HOST_DEVICE inline double diffraction_sigma_m(const LensModel& lens) {
  return 0.42 * lens.wavelength_m * working_f_number(lens);
}

// Image-side Gaussian sigma (m) of the lens blur of a point at `object_distance_m`: defocus,
// diffraction and residual aberrations in quadrature.
SLS_HOST_DEVICE inline double lens_blur_sigma_m(const LensModel& lens, double object_distance_m) {
  const double defocus = blur_circle_to_sigma(circle_of_confusion_m(lens, object_distance_m));
  const double diffraction = diffraction_sigma_m(lens);
  return std::sqrt(defocus * defocus + diffraction * diffraction + lens.residual_sigma_m * lens.residual_sigma_m);
}

// The variance of a pixel's own aperture, a box one pixel wide: 1/12 px^2 along each axis.
constexpr double kPixelApertureVariancePx2 = 1.0 / 12.0;

// The camera's lens blur alone (defocus, diffraction, aberrations), in camera pixels, for a
// surface at `object_depth_m`: what a renderer that integrates over each pixel's area itself
// applies (the pixel's aperture is then already in the integral).
SLS_HOST_DEVICE inline double lens_blur_sigma_px(const LensModel& lens, const SensorModel& sensor,
                                                 double object_depth_m) {
  return lens_blur_sigma_m(lens, object_depth_m) / sensor.pixel_pitch_m;
}

// The Gaussian sigma (camera pixels) a renderer that point-samples each pixel centre should
// apply for a surface at `object_depth_m`: the lens blur plus the pixel's own aperture (a box
// of one pixel, variance 1/12 px^2, as the Gaussian of the same variance). At the focus
// distance it is the floor (diffraction and pixel). A renderer that integrates over the pixel
// area itself should use lens_blur_sigma_px() instead, or it counts the pixel twice
// (drivers/sim/render_shared.h does either, per pixel).
SLS_HOST_DEVICE inline double defocus_sigma_px(const LensModel& lens, const SensorModel& sensor, double object_depth_m) {
  const double sigma = lens_blur_sigma_px(lens, sensor, object_depth_m);
  return std::sqrt(sigma * sigma + kPixelApertureVariancePx2);
}

// The projector lens blur, in DMD pixels along the columns (x) and the rows (y), of the
// pattern landing at `object_depth_m` (projector-frame z). The DMD pixels' own extent is not
// included: sls::pattern_value_blurred integrates each pixel exactly, so pass x as sigma_px
// for column patterns and y for row patterns.
SLS_HOST_DEVICE inline Vec2d projector_blur_sigma_px(const ProjectorModel& projector, double object_depth_m) {
  const double sigma = lens_blur_sigma_m(projector.lens, object_depth_m);
  return {sigma / projector.pixel_pitch_x_m, sigma / projector.pixel_pitch_y_m};
}

// The object distances where the blur circle reaches `max_blur_diameter_m` (image side), from
// c(s) = A f |s - s_f| / (s (s_f - f)) solved on either side of the focus.
SLS_HOST_DEVICE inline DepthOfField depth_of_field(const LensModel& lens, double max_blur_diameter_m) {
  const double f = lens.focal_length_m;
  const double s_f = lens.focus_distance_m;
  const double af = (f / lens.f_number) * f;
  const double k = max_blur_diameter_m * (s_f - f);
  DepthOfField dof;
  dof.near_m = af * s_f / (af + k);
  dof.far_m = af > k ? af * s_f / (af - k) : HUGE_VAL;
  return dof;
}

// Contrast left in a sinusoidal fringe of period `period_m` after a Gaussian blur of sigma
// (same units): the Gaussian's MTF, exp(-2 pi^2 sigma^2 / p^2).
SLS_HOST_DEVICE inline double gaussian_mtf(double sigma, double period) {
  const double r = sigma / period;
  return std::exp(-19.739208802178717 * r * r);  // 2 pi^2
}

// The projector's response to its DMD levels (ProjectorModel::gamma), for
// sls::pattern_value_blurred(desc, u, sigma, response).
struct ProjectorGammaResponse {
  double gamma;
  SLS_HOST_DEVICE double operator()(int level) const {
    return 255.0 * std::pow(static_cast<double>(level) / 255.0, gamma);
  }
};

// Relative irradiance the projector puts on the scene for a pattern value in [0, 1]
// (sls::pattern_value_blurred): the DMD's off-state light sets a floor of 1/contrast.
SLS_HOST_DEVICE inline double projector_relative_irradiance(const ProjectorModel& projector, double pattern_value) {
  const double black = projector.contrast_ratio > 1.0 ? 1.0 / projector.contrast_ratio : 0.0;
  return black + (1.0 - black) * pattern_value;
}

// Pinhole intrinsics of a thin-lens camera focused at its focus distance: the pinhole sits at
// the lens centre and the image plane at v_f, so fx = v_f / pitch, not f / pitch (they differ
// by (1 + m), a factor 2.15 for the default rig). Principal point at the image centre (pixel
// centres at integers, sdk/core/camera_model_shared.h). No distortion.
SLS_HOST_DEVICE inline CameraIntrinsics camera_intrinsics(const LensModel& lens, const SensorModel& sensor) {
  const double v = lens_image_distance_m(lens, lens.focus_distance_m);
  CameraIntrinsics k;
  k.width = sensor.width;
  k.height = sensor.height;
  k.fx = v / sensor.pixel_pitch_m;
  k.fy = v / sensor.pixel_pitch_m;
  k.cx = 0.5 * (sensor.width - 1);
  k.cy = 0.5 * (sensor.height - 1);
  return k;
}

// The projector as an inverse camera: fx and fy differ because its pixels are not square.
SLS_HOST_DEVICE inline CameraIntrinsics projector_intrinsics(const ProjectorModel& projector) {
  const double v = lens_image_distance_m(projector.lens, projector.lens.focus_distance_m);
  CameraIntrinsics k;
  k.width = projector.width;
  k.height = projector.height;
  k.fx = v / projector.pixel_pitch_x_m;
  k.fy = v / projector.pixel_pitch_y_m;
  k.cx = 0.5 * (projector.width - 1);
  k.cy = 0.5 * (projector.height - 1);
  return k;
}

// --- The default rig (docs/simulator-optics.md) ------------------------------------------

// Sony IMX304-class 12 MP global-shutter sensor (3.45 um Pregius pixel), read out as a
// 4000 x 3000 region of its 4112 x 3008 array, 12-bit ADC at its lowest gain.
SLS_HOST_DEVICE inline SensorModel default_camera_sensor() {
  SensorModel s;
  s.width = 4000;
  s.height = 3000;
  s.pixel_pitch_m = 3.45e-6;
  s.full_well_e = 10500.0;
  s.read_noise_e = 2.4;
  s.quantum_efficiency = 0.65;
  s.bit_depth = 12;
  s.gain_e_per_dn = 2.6;    // full well -> 4038 DN above black: saturation is the pixel's, not the ADC's
  s.black_level_dn = 32.0;  // > 30 sigma of the read noise (0.92 DN): the dark floor is never clipped
  s.gamma = 1.0;
  return s;
}

// Macro lens at magnification 1.15 (3.45 um pixel -> 3.0 um on the object, field 12 x 9 mm)
// focused at 100 mm: the thin-lens equation gives f = s m / (1 + m) = 53.49 mm, v = 115 mm.
// f/8 gives the +-5 mm usable depth of field (see the document).
SLS_HOST_DEVICE inline LensModel default_camera_lens() {
  const double working_distance = 0.100;
  const double magnification = 1.15;
  LensModel lens;
  lens.focal_length_m = working_distance * magnification / (1.0 + magnification);
  lens.f_number = 8.0;
  lens.focus_distance_m = working_distance;
  lens.wavelength_m = 550e-9;
  lens.residual_sigma_m = 0.0;
  return lens;
}

// DLP4500 (DLPC350) DMD: 912 x 1140 diamond array, modelled as a rectangular grid with
// 10.8 um columns and 5.4 um rows. Its lens throws a 16 x 10 mm field at 100 mm (covering
// the camera's 12 x 9 mm field with margin for the 25 degree convergence and +-5 mm depth):
// projection magnification 16 mm / 9.85 mm = 1.624, DMD at v = 61.6 mm, f = 38.1 mm, f/8.
// The thin-lens focal length that images a DMD `dmd_width_m` wide onto `field_width_m` at
// `throw_distance_m`: the DMD sits at v = s · dmd / field, and 1/f = 1/s + 1/v.
SLS_HOST_DEVICE inline double projection_focal_length_m(double throw_distance_m, double dmd_width_m,
                                                        double field_width_m) {
  const double dmd_distance = throw_distance_m * dmd_width_m / field_width_m;
  return throw_distance_m * dmd_distance / (throw_distance_m + dmd_distance);
}

SLS_HOST_DEVICE inline ProjectorModel default_projector_optics() {
  const double throw_distance = 0.100;
  const double field_width = 0.016;
  ProjectorModel p;
  p.width = 912;
  p.height = 1140;
  p.pixel_pitch_x_m = 10.8e-6;
  p.pixel_pitch_y_m = 5.4e-6;
  p.lens.focal_length_m = projection_focal_length_m(throw_distance, p.width * p.pixel_pitch_x_m, field_width);
  p.lens.f_number = 8.0;
  p.lens.focus_distance_m = throw_distance;
  p.lens.wavelength_m = 550e-9;
  p.lens.residual_sigma_m = 0.0;
  p.contrast_ratio = 1000.0;
  p.white_electrons = 0.7 * default_camera_sensor().full_well_e;  // exposure set for 70 % of full well
  return p;
}

// The 1920 x 1080 alternative: a DLP6500-class DMD (7.56 um square pixels, 14.5 x 8.2 mm),
// its lens throwing the same 16 mm wide field at 100 mm (9 mm tall: the camera's 9 mm with
// no vertical margin), f/8, the same contrast and exposure.
SLS_HOST_DEVICE inline ProjectorModel projector_optics_1080p() {
  ProjectorModel p = default_projector_optics();
  p.width = 1920;
  p.height = 1080;
  p.pixel_pitch_x_m = 7.56e-6;
  p.pixel_pitch_y_m = 7.56e-6;
  p.lens.focal_length_m = projection_focal_length_m(p.lens.focus_distance_m, p.width * p.pixel_pitch_x_m, 0.016);
  return p;
}

SLS_HOST_DEVICE inline RigOptics default_rig_optics() {
  RigOptics rig;
  rig.camera_sensor = default_camera_sensor();
  rig.camera_lens = default_camera_lens();
  rig.projector = default_projector_optics();
  rig.working_distance_m = rig.camera_lens.focus_distance_m;
  rig.triangulation_angle_rad = 25.0 * 0.017453292519943295;  // degrees -> radians
  // Both lenses 100 mm from the common focus point, axes converging at 25 degrees.
  rig.baseline_m = 2.0 * rig.working_distance_m * std::sin(0.5 * rig.triangulation_angle_rad);
  // 500 lx room light against ~84 klx of projector white on the target: 0.6 %.
  rig.ambient_electrons = 0.006 * rig.projector.white_electrons;
  return rig;
}

}  // namespace sls::sim
