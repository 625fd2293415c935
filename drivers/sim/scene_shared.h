// Analytic scenes of the simulator, shared by the CPU and CUDA renderers (DESIGN.md section 6):
// plain structs and SLS_HOST_DEVICE inline functions templated on the scalar (float on the
// GPU, double for ground truth). No Eigen, no allocation, no virtuals, no exceptions here; the
// host side (drivers/sim/scene.h) builds these structs from named, documented parameters and
// adds the ground-truth extras. docs/simulator-scenes.md gives every parameter and its basis.
//
// Units are metres. Every scene lives in its own OBJECT FRAME:
//   knurled objects: z = the object's axis (= turntable axis), origin on the axis at the bottom
//                    cap, the solid spans 0 <= z <= height; ridge k of the screw lies at angle
//                    2*pi*k/N from +x;
//   plane, chessboard: the sheet z = 0, normal +z, centred on the origin;
//   sphere:          its centre and radius are given in the frame.
// Rays are given in the object frame (origin, UNIT direction); intersect() returns the
// smallest t in (t_min, t_max) where the ray meets the surface, from either side.
#pragma once

// The primitives are in scene_primitives_shared.h, the knurled objects in knurled_shared.h;
// this header joins them into one scene type.

#include "drivers/sim/knurled_shared.h"
#include "drivers/sim/scene_primitives_shared.h"
#include "sdk/core/host_device.h"
#include "sdk/core/math_shared.h"

namespace sls::sim {

// ---------------------------------------------------------------------------------------
// A scene for the renderers: the kind plus every kind's parameters (only the one named by
// `kind` is used), passed to kernels by value.
template <typename T>
struct SceneShapeT {
  SceneKind kind = SceneKind::kPlane;
  PlaneT<T> plane;
  SphereT<T> sphere;
  ChessboardT<T> chessboard;
  KnurledScrewT<T> screw;
  KnurledKnobT<T> knob;

  template <typename U>
  SLS_HOST_DEVICE SceneShapeT<U> cast() const {
    SceneShapeT<U> o;
    o.kind = kind;
    o.plane = plane.template cast<U>();
    o.sphere = sphere.template cast<U>();
    o.chessboard = chessboard.template cast<U>();
    o.screw = screw.template cast<U>();
    o.knob = knob.template cast<U>();
    return o;
  }
};

template <typename T>
SLS_HOST_DEVICE inline bool intersect(const SceneShapeT<T>& s, const RayT<T>& ray, T t_min, T t_max, HitT<T>* hit) {
  switch (s.kind) {
    case SceneKind::kPlane: return intersect_plane(s.plane, ray, t_min, t_max, hit);
    case SceneKind::kSphere: return intersect_sphere(s.sphere, ray, t_min, t_max, hit);
    case SceneKind::kChessboard: return intersect_chessboard(s.chessboard, ray, t_min, t_max, hit);
    case SceneKind::kKnurledScrew: return intersect_knurled_screw(s.screw, ray, t_min, t_max, hit);
    case SceneKind::kKnurledKnob: return intersect_knurled_knob(s.knob, ray, t_min, t_max, hit);
  }
  return false;
}

// The albedo at a surface point p (for renderers that find points another way).
template <typename T>
SLS_HOST_DEVICE inline T surface_albedo(const SceneShapeT<T>& s, Vec3T<T> p) {
  switch (s.kind) {
    case SceneKind::kPlane: return detail::clamp(s.plane.albedo, T(0), T(1));
    case SceneKind::kSphere: return detail::clamp(s.sphere.albedo, T(0), T(1));
    case SceneKind::kChessboard: return chessboard_albedo(s.chessboard, p.x, p.y);
    case SceneKind::kKnurledScrew: return albedo_at(s.screw.albedo, p);
    case SceneKind::kKnurledKnob: return albedo_at(s.knob.albedo, p);
  }
  return T(0);
}

}  // namespace sls::sim
