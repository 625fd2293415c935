// The simulator's boards against closed form: a chessboard's edges lie where they project at
// every sub-pixel phase, and the albedo integrated over each pixel's footprint is the exact
// area integral for the chessboard and the ChArUco board and converges with the samples for a
// texture.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/render_shared.h"
#include "drivers/sim/renderer.h"
#include "sdk/core/camera_model_shared.h"
#include "tests/support/test_support.h"
#include "tests/unit/sim/sim_test_rig.h"

namespace sls::sim {
namespace {

// Where the sheet's line x = x0 (object frame) crosses the centre of image row `row`: the
// exact projection (lens distortion included), by bisection over the line's y in [y0, y1].
Eigen::Vector2d sheet_line_at_row(const SimRig& rig, const Pose& T_camera_object, double x0, double y0, double y1,
                                  double row) {
  const auto pixel = [&](double y) {
    const Eigen::Vector3d c = T_camera_object * Eigen::Vector3d(x0, y, 0.0);
    Vec2d uv{NAN, NAN};
    project(rig.camera, Vec3d{c.x(), c.y(), c.z()}, &uv);
    return Eigen::Vector2d(uv.x, uv.y);
  };
  const double sign = pixel(y1).y() > pixel(y0).y() ? 1.0 : -1.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (y0 + y1);
    if (sign * (pixel(mid).y() - row) > 0.0) {
      y1 = mid;
    } else {
      y0 = mid;
    }
  }
  return pixel(0.5 * (y0 + y1));
}

// A least-squares line through (x, values[x]) for x in [first, last], evaluated at `at`.
double line_fit_at(const Image16u& image, int row, int first, int last, double at) {
  double n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (int x = first; x <= last; ++x) {
    const double v = image(x, row);
    n += 1;
    sx += x;
    sy += v;
    sxx += static_cast<double>(x) * x;
    sxy += x * v;
  }
  const double slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
  return (sy - slope * sx) / n + slope * at;
}

// A camera pixel integrates the irradiance over its area: a noise-free white image of a
// chessboard puts each edge between a dark and a light square where it projects, whatever the
// edge's sub-pixel phase. Evidence without a corner detector: along a pixel row crossing a
// vertical edge, pixel i holds dark + (light − dark) · (the share of its width beyond the
// edge) — with the lens blur on top, which moves light between pixels but keeps the sum —
// so Σ_i (value_i − dark_i) / (light_i − dark_i) over the row is the length of row beyond the
// edge, i.e. gives the edge's column (the 50 % crossing of the area-integrated profile). Point
// sampling at the pixel centres (the renderer before) rounds each edge to the pixel grid: up
// to ±0.5 px off.
TEST(Renderer, ChessboardEdgesLieWhereTheyProjectAtEverySubPixelPhase) {
  const Scene scene = make_chessboard_scene();  // 1.2 mm squares: 40 pixels at ci 400
  SimRig rig = small_rig(scene, 400);
  rig.noise = false;
  ASSERT_EQ(rig.patterns.patterns[0].kind, PatternKind::kWhite);
  // The board as a scan stands it, slid sideways by k/7 of a pixel (frames 0-6), then 1.5 mm
  // nearer (camera blur 0.8 px) slid by k/3 of a pixel (frames 7-9).
  const double pixel_m = rig.optics.working_distance_m / rig.camera.fx;
  for (int k = 0; k < 10; ++k) {
    const bool near = k >= 7;
    const double slide = near ? (k - 7) / 3.0 : k / 7.0;
    const Pose shift(Eigen::Quaterniond::Identity(), Eigen::Vector3d(near ? 1.5e-3 : 0.0, slide * pixel_m, 0.0));
    rig.placements.push_back({std::nullopt, shift * rig.T_table_object});
  }
  const ChessboardT<double>& board = scene.shape().chessboard;
  Renderer renderer(rig, scene, Device::cpu());
  double worst_px = 0.0, sum_squares = 0.0;
  int rows = 0;
  bool phases[10] = {};
  for (int frame = 0; frame < static_cast<int>(rig.placements.size()); ++frame) {
    renderer.set_frame(frame);
    const Image16u white = renderer.render_pattern(0);
    const Pose T_camera_object = rig.T_object_camera(frame).inverse();
    double frame_worst = 0.0;
    // The vertical edges between square columns 2 .. 7, along square rows 2 .. 5, 0.3 mm
    // (10 pixels) clear of the horizontal edges.
    for (int i = 3; i <= 7; ++i) {
      const double x0 = (i - 0.5 * board.squares_x) * board.square;
      for (int j = 2; j <= 5; ++j) {
        const double y0 = (j - 0.5 * board.squares_y) * board.square + 0.3e-3;
        const double y1 = y0 + board.square - 0.6e-3;
        const Eigen::Vector2d a = sheet_line_at_row(rig, T_camera_object, x0, y0, y1, -1e9);
        const Eigen::Vector2d b = sheet_line_at_row(rig, T_camera_object, x0, y0, y1, 1e9);
        for (int row = static_cast<int>(std::ceil(std::min(a.y(), b.y())));
             row <= static_cast<int>(std::floor(std::max(a.y(), b.y()))); ++row) {
          const double edge = sheet_line_at_row(rig, T_camera_object, x0, y0, y1, row).x();
          const int centre = static_cast<int>(std::lround(edge));
          // Levels each side from pixels 6 .. 14 away, as lines (the light falls off slowly).
          const double at_left = line_fit_at(white, row, centre - 14, centre - 6, centre);
          const double at_right = line_fit_at(white, row, centre + 6, centre + 14, centre);
          ASSERT_GT(std::fabs(at_right - at_left), 1000.0) << "frame " << frame << " row " << row;
          double beyond = 0.0;  // the length of row [centre − 4.5, centre + 4.5] beyond the edge
          for (int x = centre - 4; x <= centre + 4; ++x) {
            const double left = line_fit_at(white, row, centre - 14, centre - 6, x);
            const double right = line_fit_at(white, row, centre + 6, centre + 14, x);
            beyond += (white(x, row) - left) / (right - left);
          }
          const double measured = centre + 4.5 - beyond;
          const double error = measured - edge;
          worst_px = std::max(worst_px, std::fabs(error));
          frame_worst = std::max(frame_worst, std::fabs(error));
          sum_squares += error * error;
          ++rows;
          phases[static_cast<int>(std::floor(10.0 * (edge - std::floor(edge))))] = true;
        }
      }
    }
    std::printf("frame %d: worst edge error %.4f px\n", frame, frame_worst);
  }
  std::printf("chessboard edges: %d rows, edge column error RMS %.4f px, worst %.4f px\n", rows,
              std::sqrt(sum_squares / rows), worst_px);
  EXPECT_GT(rows, 1000);
  for (int bin = 0; bin < 10; ++bin) EXPECT_TRUE(phases[bin]) << "no edge at sub-pixel phase " << bin / 10.0;
  EXPECT_LT(worst_px, 0.02);
}

// chessboard_mean_albedo() against a brute-force midpoint sum over parallelogram footprints
// anywhere on and off the board (pixel-sized and spanning several squares), the exact mean at
// an X-junction whatever the footprint's turn, the albedo-weighted centroid of a footprint
// halved by an edge, and the refusal of a footprint over too many squares.
TEST(Renderer, ChessboardFootprintAlbedoIsTheExactAreaIntegral) {
  const ChessboardT<double> board = make_chessboard_scene().shape().chessboard;  // 1.2 mm squares
  const double range = board.albedo_light - board.albedo_dark;
  NoiseStream draws = make_noise_stream(NoiseKey{7, 0, 0, 0}, 0);
  const auto parallelogram = [](Vec2d centre, Vec2d a, Vec2d b, Vec2d* quad) {
    quad[0] = centre - 0.5 * a - 0.5 * b;
    quad[1] = centre + 0.5 * a - 0.5 * b;
    quad[2] = centre + 0.5 * a + 0.5 * b;
    quad[3] = centre - 0.5 * a + 0.5 * b;
  };
  double worst = 0.0, worst_centroid = 0.0;
  for (int trial = 0; trial < 120; ++trial) {
    // Centres on and off the plate, a third of them near an inner corner; sides of 10 .. 60
    // µm (pixels), every tenth 0.5 .. 3 mm (over several squares), sheared by up to 50°.
    Vec2d centre{14e-3 * (draws.uniform() - 0.5), 12e-3 * (draws.uniform() - 0.5)};
    if (trial % 3 == 0) {
      centre = {(std::round(centre.x / board.square) + 0.02 * (draws.uniform() - 0.5)) * board.square,
                (std::round(centre.y / board.square) + 0.02 * (draws.uniform() - 0.5)) * board.square};
    }
    const double size = trial % 10 == 9 ? 0.5e-3 + 2.5e-3 * draws.uniform() : 10e-6 + 50e-6 * draws.uniform();
    const double angle = 2.0 * M_PI * draws.uniform(), shear = (draws.uniform() - 0.5) * 100.0 * M_PI / 180.0;
    const Vec2d a{size * std::cos(angle), size * std::sin(angle)};
    const double length_b = size * (0.5 + draws.uniform());
    const Vec2d b{length_b * std::cos(angle + M_PI / 2 + shear), length_b * std::sin(angle + M_PI / 2 + shear)};
    Vec2d quad[4];
    parallelogram(centre, a, b, quad);
    double albedo = 0.0;
    Vec2d centroid{0.0, 0.0};
    ASSERT_TRUE(chessboard_mean_albedo(board, quad, &albedo, &centroid)) << "trial " << trial;
    constexpr int kSteps = 1000;
    double sum = 0.0;
    Vec2d weighted{0.0, 0.0};
    for (int j = 0; j < kSteps; ++j) {
      for (int i = 0; i < kSteps; ++i) {
        const Vec2d p = centre + ((i + 0.5) / kSteps - 0.5) * a + ((j + 0.5) / kSteps - 0.5) * b;
        const double value = chessboard_albedo(board, p.x, p.y);
        sum += value;
        weighted = weighted + value * p;
      }
    }
    const double reference = sum / (kSteps * kSteps);
    worst = std::max(worst, std::fabs(albedo - reference) / range);
    const Vec2d reference_centroid = (1.0 / sum) * weighted;
    worst_centroid = std::max(worst_centroid, std::hypot(centroid.x - reference_centroid.x,
                                                         centroid.y - reference_centroid.y) / size);
  }
  std::printf("chessboard footprints: worst difference from a 1000 x 1000 midpoint sum %.2g of the albedo range, "
              "centroid %.2g of the footprint\n", worst, worst_centroid);
  EXPECT_LT(worst, 1e-3);  // the midpoint sum's own error: an edge moves it by < 1/1000
  EXPECT_LT(worst_centroid, 1e-3);

  // Centred on an inner corner, a square footprint turned by any angle is half dark, half
  // light (a quarter turn maps it onto itself and the dark quadrants onto the light ones).
  for (int k = 0; k < 8; ++k) {
    const double angle = 0.3 + 0.7 * k;
    const Vec2d a{30e-6 * std::cos(angle), 30e-6 * std::sin(angle)};
    const Vec2d b{-a.y, a.x};
    Vec2d quad[4];
    parallelogram({board.square, -board.square}, a, b, quad);
    double albedo = 0.0;
    ASSERT_TRUE(chessboard_mean_albedo(board, quad, &albedo));
    EXPECT_NEAR(albedo, 0.5 * (board.albedo_dark + board.albedo_light), 1e-12) << angle;
  }
  // A square footprint halved by a vertical edge between a dark square (left) and a light one:
  // its light comes from 0.2 of its width right of the edge, ((l − d) / (l + d)) / 4.
  const double h = 30e-6;
  const double edge = -board.square;  // between columns 3 and 4 at row 3: dark, then light
  Vec2d quad[4];
  parallelogram({edge, -0.5 * board.square}, {h, 0.0}, {0.0, h}, quad);
  ASSERT_EQ(chessboard_albedo(board, edge - h / 4, -0.5 * board.square), board.albedo_dark);
  ASSERT_EQ(chessboard_albedo(board, edge + h / 4, -0.5 * board.square), board.albedo_light);
  double albedo = 0.0;
  Vec2d centroid{0.0, 0.0};
  ASSERT_TRUE(chessboard_mean_albedo(board, quad, &albedo, &centroid));
  EXPECT_NEAR(albedo, 0.5, 1e-12);
  EXPECT_NEAR(centroid.x - edge,
              0.25 * h * (board.albedo_light - board.albedo_dark) / (board.albedo_light + board.albedo_dark), 1e-15);
  EXPECT_NEAR(centroid.y, -0.5 * board.square, 1e-15);
  // Over more than kChessboardMaxFootprintSquares squares: left to the caller.
  parallelogram({0.0, 0.0}, {12e-3, 0.0}, {0.0, 9e-3}, quad);
  EXPECT_FALSE(chessboard_mean_albedo(board, quad, &albedo));
}

// A ChArUco board's footprint albedo (its dark squares and its markers' dark cells, each
// clipped to the footprint) against a brute-force midpoint sum, as the chessboard's above; its
// point albedo against the table it was made from; the scene's name and parameters.
TEST(Renderer, CharucoFootprintAlbedoIsTheExactAreaIntegral) {
  const ChessboardParameters parameters = synthetic_charuco();
  const Scene scene = make_chessboard_scene(parameters);
  EXPECT_EQ(scene.name(), "charuco");
  EXPECT_TRUE(scene.to_json().find("\"charuco\"") != std::string::npos);
  const ChessboardT<double>& board = scene.shape().chessboard;
  ASSERT_TRUE(board.is_charuco());
  // The table in the board frame (y down the board) at cell centres: board square (I, J),
  // cell (r, c) lies at sheet x = −5 s + I s + offset + (c + ½) cell, sheet y = 4 s − J s −
  // offset − (r + ½) cell (the board frame's y is the sheet's flipped).
  const double s = board.square, cell = board.marker / board.marker_cells, offset = 0.5 * (s - board.marker);
  int checked = 0;
  for (int J = 0; J < 8; ++J) {
    for (int I = 0; I < 10; ++I) {
      const std::size_t square = static_cast<std::size_t>(J * 10 + I);
      for (int r = 0; r < board.marker_cells; ++r) {
        for (int c = 0; c < board.marker_cells; ++c) {
          const double x = -5.0 * s + I * s + offset + (c + 0.5) * cell;
          const double y = 4.0 * s - J * s - offset - (r + 0.5) * cell;
          const bool dark = parameters.charuco.dark_square[square] != 0 ||
                            parameters.charuco.dark_cells[square * 49 + static_cast<std::size_t>(r * 7 + c)] != 0;
          ASSERT_EQ(chessboard_albedo(board, x, y), dark ? board.albedo_dark : board.albedo_light)
              << I << ", " << J << " cell " << r << ", " << c;
          ++checked;
        }
      }
    }
  }
  EXPECT_EQ(checked, 80 * 49);
  const double range = board.albedo_light - board.albedo_dark;
  NoiseStream draws = make_noise_stream(NoiseKey{11, 0, 0, 0}, 0);
  double worst = 0.0;
  for (int trial = 0; trial < 60; ++trial) {
    const Vec2d centre{14e-3 * (draws.uniform() - 0.5), 12e-3 * (draws.uniform() - 0.5)};
    // Pixel-sized (10 .. 60 µm) and every tenth 0.2 .. 0.6 mm (over several cells).
    const double size = trial % 10 == 9 ? 0.2e-3 + 0.4e-3 * draws.uniform() : 10e-6 + 50e-6 * draws.uniform();
    const double angle = 2.0 * M_PI * draws.uniform();
    const Vec2d a{size * std::cos(angle), size * std::sin(angle)};
    const Vec2d b{-a.y * 0.8, a.x * 0.8};
    const Vec2d quad[4] = {centre - 0.5 * a - 0.5 * b, centre + 0.5 * a - 0.5 * b, centre + 0.5 * a + 0.5 * b,
                           centre - 0.5 * a + 0.5 * b};
    double albedo = 0.0;
    ASSERT_TRUE(chessboard_mean_albedo(board, quad, &albedo)) << "trial " << trial;
    constexpr int kSteps = 1000;
    double sum = 0.0;
    for (int j = 0; j < kSteps; ++j) {
      for (int i = 0; i < kSteps; ++i) {
        const Vec2d p = centre + ((i + 0.5) / kSteps - 0.5) * a + ((j + 0.5) / kSteps - 0.5) * b;
        sum += chessboard_albedo(board, p.x, p.y);
      }
    }
    worst = std::max(worst, std::fabs(albedo - sum / (kSteps * kSteps)) / range);
  }
  std::printf("charuco footprints: worst difference from a 1000 x 1000 midpoint sum %.2g of the albedo range\n", worst);
  EXPECT_LT(worst, 2e-3);  // the midpoint sum's own error (more edges per footprint than a chessboard's)
}

// The footprint of a pixel `pixel_m` wide at (0.1 m) on the plane through `point` with
// `normal`, seen from `towards` (unit, on the normal's side), its rows turned by `turn`.
PixelFootprint footprint_at(Vec3d point, Vec3d normal, Vec3d towards, double pixel_m, double turn) {
  const Vec3d helper = std::fabs(towards.z) < 0.9 ? Vec3d{0.0, 0.0, 1.0} : Vec3d{1.0, 0.0, 0.0};
  Vec3d e1 = cross(helper, towards);
  e1 = (1.0 / norm(e1)) * e1;
  const Vec3d e2 = cross(towards, e1);
  PixelFootprint f;
  f.origin = point + 0.1 * towards;
  f.ray = -1.0 * towards;
  f.ray_per_px_x = (pixel_m / 0.1) * (std::cos(turn) * e1 + std::sin(turn) * e2);
  f.ray_per_px_y = (pixel_m / 0.1) * (-std::sin(turn) * e1 + std::cos(turn) * e2);
  f.normal = normal;
  f.offset = dot(point - f.origin, normal);
  return f;
}

// The choice of the footprint's sampling, by convergence. A smooth solid texture (the
// tracker tests': amplitude 0.3, periods 1 and 4 mm; pixels of 37.5 µm seen at up to 73° from
// the normal) converges as 1/N²: N = 4 leaves up to 4e-4 of the albedo (about 1 DN at full
// white), kTextureSamplesPerAxis = 8 1e-4 (a third of a DN), against N = 64. The chessboard
// sampled on an N x N grid converges only as 1/N (an edge along a row of samples jumps by 1/N
// of the pixel: 0.13 px at N = 4, 0.06 px at N = 8), hence its exact integral.
TEST(Renderer, FootprintAlbedoConvergesWithTheSamples) {
  NoiseStream draws = make_noise_stream(NoiseKey{11, 0, 0, 0}, 0);
  const auto random_unit = [&draws]() {
    const double z = 2.0 * draws.uniform() - 1.0, phi = 2.0 * M_PI * draws.uniform();
    const double r = std::sqrt(1.0 - z * z);
    return Vec3d{r * std::cos(phi), r * std::sin(phi), z};
  };
  for (const double period : {1e-3, 4e-3}) {
    KnurledKnobParameters parameters;
    parameters.albedo = {0.5, 0.3, period};
    const SceneShapeT<double> scene = make_knurled_knob_scene(parameters).shape();
    ASSERT_TRUE(albedo_varies(scene));
    double worst[5] = {};  // N = 1, 2, 4, 8, 16 against N = 64
    for (int trial = 0; trial < 300; ++trial) {
      const Vec3d point = 10e-3 * random_unit();
      const Vec3d normal = random_unit();
      Vec3d towards = random_unit();
      if (dot(towards, normal) < 0.3) towards = (1.0 / norm(towards + normal)) * (towards + normal);
      if (dot(towards, normal) < 0.3) towards = normal;
      const PixelFootprint f = footprint_at(point, normal, towards, 37.5e-6, draws.uniform());
      FootprintAlbedo reference, a[5];
      ASSERT_TRUE(footprint_albedo<64>(scene, f, &reference));
      ASSERT_TRUE(footprint_albedo<1>(scene, f, &a[0]));
      ASSERT_TRUE(footprint_albedo<2>(scene, f, &a[1]));
      ASSERT_TRUE(footprint_albedo<4>(scene, f, &a[2]));
      ASSERT_TRUE(footprint_albedo<8>(scene, f, &a[3]));
      ASSERT_TRUE(footprint_albedo<16>(scene, f, &a[4]));
      for (int k = 0; k < 5; ++k) worst[k] = std::max(worst[k], std::fabs(a[k].albedo - reference.albedo));
    }
    std::printf("texture of period %.0f mm, 37.5 um pixels: worst |mean − mean(N = 64)| for N = 1, 2, 4, 8, 16: "
                "%.2g %.2g %.2g %.2g %.2g\n", period * 1e3, worst[0], worst[1], worst[2], worst[3], worst[4]);
    EXPECT_EQ(kTextureSamplesPerAxis, 8);
    EXPECT_LT(worst[3], 1.5e-4);
    for (int k = 1; k < 5; ++k) EXPECT_LT(worst[k], worst[k - 1] / 3.0) << k;  // 1/N²: a quarter per doubling
  }

  // The chessboard: the exact integral against N x N samples of the same footprint, for
  // pixels of 30 µm (ci at 400 px) seen nearly square on, rows turned by up to ±10°; the
  // error as a share of the albedo range is what it moves an edge, in pixels.
  const SceneShapeT<double> board = make_chessboard_scene().shape();
  const double range = board.chessboard.albedo_light - board.chessboard.albedo_dark;
  const int sample_counts[4] = {2, 4, 8, 16};
  double worst[4] = {};
  for (int trial = 0; trial < 2000; ++trial) {
    // Near a vertical edge (x = 0), anywhere along it.
    const Vec3d point{30e-6 * (draws.uniform() - 0.5), 4e-3 * (draws.uniform() - 0.5), 0.0};
    const Vec3d towards{0.1 * (draws.uniform() - 0.5), 0.1 * (draws.uniform() - 0.5), 1.0};
    const PixelFootprint f = footprint_at(point, {0.0, 0.0, 1.0}, (1.0 / norm(towards)) * towards, 30e-6,
                                          (draws.uniform() - 0.5) * 20.0 * M_PI / 180.0);
    FootprintAlbedo exact;
    ASSERT_TRUE(footprint_albedo(board, f, &exact));
    for (int k = 0; k < 4; ++k) {
      const int n = sample_counts[k];
      double sum = 0.0;
      for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
          Vec3d p;
          ASSERT_TRUE(footprint_point(f, (i + 0.5) / n - 0.5, (j + 0.5) / n - 0.5, &p));
          sum += surface_albedo(board, p);
        }
      }
      worst[k] = std::max(worst[k], std::fabs(sum / (n * n) - exact.albedo) / range);
    }
  }
  std::printf("chessboard, 30 um pixels: worst edge shift of N x N samples against the exact integral for "
              "N = 2, 4, 8, 16: %.3f %.3f %.3f %.3f px\n", worst[0], worst[1], worst[2], worst[3]);
  for (int k = 0; k < 4; ++k) EXPECT_GT(worst[k], 0.25 / sample_counts[k]) << sample_counts[k];  // only 1/N
}

}  // namespace
}  // namespace sls::sim
