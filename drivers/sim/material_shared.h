// Surface finish of the simulated object, shared by the CPU and CUDA renderers
// (drivers/sim/render_shared.h): the scene's albedo is the Lambertian part; a metal adds a
// specular lobe lit by the projector, which is what saturates a camera on machined parts
// and what HDR capture (sdk/decode/hdr_fusion.h) is for.
//
// BRDF: normalised Blinn-Phong, f = k_d / pi + k_s (s + 8) / (8 pi) (n.h)^s, h the unit half
// vector between the directions to the projector and to the camera. The renderer's
// Lambertian model gives radiance albedo * E / pi for irradiance E, so the material enters
// it as an equivalent albedo pi f (material_reflectance()).
//
// "metal" (machined, unpainted steel; values and basis in docs/simulator.md):
//   k_d = 0.25 x the scene albedo (0.15 on the screw's 0.6): the diffuse share a machined
//     steel surface scatters, well below paint's;
//   k_s = 0.55: the normal-incidence reflectance of iron at 550 nm (Fresnel's rise at grazing
//     angles is left out: it only brightens highlights that already clip);
//   s = 30: a surface of rms facet slope alpha = 0.25 rad (turned or knurled, Ra ~1 um),
//     through s = 2 / alpha^2 - 2.
#pragma once

#include <cmath>

#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::sim {

struct SurfaceMaterial {
  double diffuse_scale = 1.0;  // k_d / scene albedo
  double specular = 0.0;       // k_s; 0: Lambertian (painted)
  double shininess = 0.0;      // Blinn-Phong exponent s
};

// Equivalent Lambertian albedo (pi times the BRDF) of a point of `albedo` with unit normal
// `normal`, lit from unit direction `towards_light`, seen from unit direction `towards_camera`.
// Lambertian (specular 0): albedo * diffuse_scale, exactly.
SLS_HOST_DEVICE inline double material_reflectance(const SurfaceMaterial& m, double albedo, Vec3d normal,
                                                   Vec3d towards_light, Vec3d towards_camera) {
  const double diffuse = m.diffuse_scale * albedo;
  if (!(m.specular > 0.0)) return diffuse;
  const Vec3d sum = towards_light + towards_camera;
  const double length = norm(sum);
  if (!(length > 0.0)) return diffuse;
  const double cos_half = dot(normal, sum) / length;
  if (!(cos_half > 0.0)) return diffuse;
  return diffuse + m.specular * (m.shininess + 8.0) / 8.0 * std::pow(cos_half, m.shininess);
}

// The named finishes: "painted" (Lambertian, the scene's albedo) and "metal" (above).
// Returns false for another name.
inline bool surface_material_by_name(const char* name, SurfaceMaterial* out) {
  const auto equal = [](const char* a, const char* b) {
    while (*a != '\0' && *a == *b) ++a, ++b;
    return *a == *b;
  };
  if (equal(name, "painted")) {
    *out = SurfaceMaterial{};
    return true;
  }
  if (equal(name, "metal")) {
    *out = SurfaceMaterial{0.25, 0.55, 30.0};
    return true;
  }
  return false;
}

}  // namespace sls::sim
