// The simulator's scenes on the host: built by name from documented parameters, with the
// ground truth the quality metrics need (DESIGN.md section 4): exact signed distance, the
// crease set (knurl ridges, grooves, cap edges) and distance to it, a dense reference cloud
// with exact normals, and a JSON description. Renderers take shape() (double) or
// shape_float() and call the shared code of drivers/sim/scene_shared.h.
//
// Scenes (docs/simulator-scenes.md has every value and its basis):
//   "knurled-screw"  the paper's knurled head screw: straight knurl, D 32.2 mm, H 14.8 mm
//   "knurled-knob"   the paper's knurled knob: wave knurl, D 34 mm, H 7.25 mm
//   "plane"          the sheet z = 0 (tests)
//   "sphere"         a sphere (tests)
//   "chessboard"     a 10 x 8 square calibration target (9 x 7 inner corners)
// All lengths in metres, in the scene's object frame (scene_shared.h).
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "drivers/sim/scene_shared.h"
#include "sdk/core/point_cloud.h"

namespace sls::sim {

// Straight knurl (DIN 82 / ISO 13444 style, 90 degree V): N = round(pi D / pitch) teeth,
// ridges on the diameter, roots where the two flanks meet at groove_angle_deg.
struct KnurledScrewParameters {
  double diameter = 0.0322;       // ridge diameter (paper: D = 32.2 mm)
  double height = 0.0148;         // paper: H = 14.8 mm
  double nominal_pitch = 0.001;   // paper: d = 1 mm between knurl lines
  double groove_angle_deg = 90.0; // included angle of the V groove
  AlbedoT<double> albedo{0.6, 0.0, 0.001};  // painted steel: uniform grey by default
};

// Wave knurl: the ridges of a straight knurl shifted sideways by
// wave_amplitude_pitches * pitch * sin(2 pi z / wave_length).
struct KnurledKnobParameters {
  double diameter = 0.034;          // outer (ridge) diameter (paper: De = 34 mm)
  double height = 0.00725;          // paper: H = 7.25 mm
  double nominal_pitch = 0.001;     // as the screw
  double groove_angle_deg = 90.0;   // depth as for a straight knurl with this V
  double wave_amplitude_pitches = 0.5;  // ridges swing +-0.5 pitch
  double wave_length = 0.00725;     // one full wave over the height
  AlbedoT<double> albedo{0.6, 0.0, 0.001};
};

struct PlaneParameters {
  double half_extent_x = 0.0;  // <= 0 (both): unbounded
  double half_extent_y = 0.0;
  double albedo = 0.6;
};

struct SphereParameters {
  Eigen::Vector3d center{0.0, 0.0, 0.0};
  double radius = 0.01;
  double albedo = 0.6;
};

// A ChArUco board's printed pattern as plain bits (calib::BoardPattern's, which comes from
// OpenCV's dictionary: the simulator never includes OpenCV, and no marker is typed in by
// hand). In the calibration's board frame (sim_calibration_capture.h: x right, y down the
// board, origin at the first inner corner): square (I, J) spans [(I − 1) s, I s] x
// [(J − 1) s, J s], index J * squares_x + I.
struct CharucoPattern {
  double marker = 0.0;      // marker side (m), centred in its square
  int cells = 0;            // per marker side, its one-cell dark border included (≤ kCharucoMaxCells)
  std::string dictionary;   // the name it came from (ground truth only)
  std::vector<std::uint8_t> dark_square;  // per square: 1 dark (no marker)
  std::vector<std::uint8_t> dark_cells;   // per square cells * cells, r * cells + c (r along y, c along x)
};

struct ChessboardParameters {
  int inner_corners_x = 9;  // as the procam data set (DESIGN.md section 8): 10 x 8 squares
  int inner_corners_y = 7;
  double square = 0.0012;   // 12.0 x 9.6 mm of squares
  double margin = 0.0006;   // light border around the squares
  double albedo_dark = 0.1;
  double albedo_light = 0.9;
  // A ChArUco board when charuco.cells > 0: its squares from the table (not by parity), its
  // markers in the light squares; the scene is named "charuco".
  CharucoPattern charuco;

  bool is_charuco() const { return charuco.cells > 0; }
};

// Makes the ChArUco board `spec` ("charuco" or "charuco:COLSxROWS" squares) on `geometry`. Its
// markers come from OpenCV's dictionary through calib, on which the drivers do not depend
// (DESIGN.md section 2): whoever opens a sim:// calibration target with board=charuco hands one
// in (drivers::OpenOptions::sim_charuco_board; the SDK's: sdk/session/sim_charuco_board.h).
using CharucoBoardMaker =
    std::function<ChessboardParameters(const std::string& spec, const ChessboardParameters& geometry)>;

// A point of the dense reference sampling.
struct SurfaceSample {
  Eigen::Vector3d position;
  Eigen::Vector3d normal;  // unit, outward
  int part = kPartSide;    // SurfacePart
};

// Optional restriction of the reference samples to min <= z <= max.
struct ZRange {
  double min = -std::numeric_limits<double>::infinity();
  double max = std::numeric_limits<double>::infinity();
};

using Polyline = std::vector<Eigen::Vector3d>;

// An immutable scene; copies share their data.
class Scene {
 public:
  const std::string& name() const;
  SceneKind kind() const;
  const SceneShapeT<double>& shape() const;
  SceneShapeT<float> shape_float() const;

  // The first surface point with t in (t_min, t_max); false if none.
  bool intersect(const Ray& ray, double t_min, double t_max, Hit* hit) const;

  // Exact signed Euclidean distance to the surface, negative inside the solid. Sheets (plane,
  // chessboard) have no inside: the distance to the (finite) sheet, signed by the side (z).
  // The knurled knob's is numerical (local minimisation over the surface parameters),
  // accurate to well below 1e-9 m.
  double signed_distance(const Eigen::Vector3d& p) const;

  // The crease set: knurl ridge and groove lines and the cap outlines, as polylines (the
  // knob's curves are sampled so each polyline stays within 0.1 um of its curve). Empty for
  // the plane, sphere and chessboard.
  const std::vector<Polyline>& creases() const;
  // Distance from p to the nearest crease polyline (+infinity when there are none). Uses an
  // angle x height grid, so only creases near p are tested.
  double distance_to_creases(const Eigen::Vector3d& p) const;

  // Samples on the surface about `spacing` apart with exact normals, restricted to z_range.
  // Sheets are sampled over their extent (an unbounded plane over +-10 mm).
  std::vector<SurfaceSample> reference_samples(double spacing, const ZRange& z_range = {}) const;
  // The same as a point cloud with normals (float positions: rounding adds up to ~1e-9 m).
  PointCloud reference_cloud(double spacing, const ZRange& z_range = {}) const;

  // Chessboard only (else sls::Error kInvalidArgument): the inner corners in the board frame,
  // row by row (x fastest), as OpenCV lists object points.
  std::vector<Eigen::Vector3d> chessboard_corners() const;

  // {"name": ..., "units": "m", "frame": ..., "parameters": {...}, "derived": {...}};
  // scene_from_json(to_json()) rebuilds the scene.
  std::string to_json() const;

  struct Impl;

 private:
  explicit Scene(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}
  std::shared_ptr<const Impl> impl_;

  friend Scene make_knurled_screw_scene(const KnurledScrewParameters& parameters);
  friend Scene make_knurled_knob_scene(const KnurledKnobParameters& parameters);
  friend Scene make_plane_scene(const PlaneParameters& parameters);
  friend Scene make_sphere_scene(const SphereParameters& parameters);
  friend Scene make_chessboard_scene(const ChessboardParameters& parameters);
};

// Throw sls::Error (kInvalidArgument) for parameters that describe no valid object.
Scene make_knurled_screw_scene(const KnurledScrewParameters& parameters = {});
Scene make_knurled_knob_scene(const KnurledKnobParameters& parameters = {});
Scene make_plane_scene(const PlaneParameters& parameters = {});
Scene make_sphere_scene(const SphereParameters& parameters = {});
Scene make_chessboard_scene(const ChessboardParameters& parameters = {});

// The names make_scene() knows.
std::vector<std::string> scene_names();
// The named scene with its default parameters; sls::Error (kInvalidArgument) naming the known
// scenes for an unknown name.
Scene make_scene(const std::string& name);
// From {"name": ..., "parameters": {...}} (parameters optional, each one optional; "derived"
// and other top-level keys are ignored). sls::Error: kFormat for malformed JSON or wrongly
// typed values, kInvalidArgument for an unknown scene or parameter name.
Scene scene_from_json(const std::string& json);

// Knurl geometry (docs/simulator-scenes.md): teeth N = round(pi D / pitch), and the root
// radius where two flanks from ridges at +-pi/N meet at the groove angle:
//   r = R (cos(pi/N) - sin(pi/N) / tan(angle / 2)).
int knurl_teeth(double diameter, double nominal_pitch);
double knurl_root_radius(double ridge_radius, int teeth, double groove_angle_rad);

}  // namespace sls::sim
