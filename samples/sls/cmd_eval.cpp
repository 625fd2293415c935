// sls eval: the quality of a fused result against a simulated recording's ground truth
// (DESIGN.md section 4; definitions in sdk/eval/evaluate.h): C2C mean / RMS / 95th
// percentile, edge-region C2C, coverage of the surface the recording saw, and with a
// trajectory.txt in the result, ATE and the loop-closure error against the true poses. A scan
// with online deformation leaves the model as tracked in OUT/undeformed (cloud.ply,
// trajectory.txt): it is measured too, at the result's voxel size, and printed beside the
// deformed figures ("undeformed" in --json).
//
//   sls eval --result OUT --truth OUT/recording [--json]
#include <cmath>
#include <iostream>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "samples/sls/commands.h"
#include "sdk/eval/eval_json.h"
#include "sdk/eval/evaluate.h"
#include "sdk/eval/evaluate_regions.h"
#include "sdk/core/error.h"

namespace sls::cli {
namespace {

struct EvalCommandOptions {
  std::string result;
  std::string truth;
  double voxel_um = 0.0;
  eval::EvalOptions eval;
  bool no_align = false;
  std::string raw_scan;    // the paper's Table I: a view's raw depth map ...
  int raw_scan_frame = 0;  // ... of this frame
};

constexpr double kUm = 1e6;

std::string figure_text(const nlohmann::json& evaluation, const eval::SideBySideFigure& figure) {
  const auto found = evaluation.find(figure.key);
  if (found == evaluation.end() || !found->is_number()) return "n/a";
  const char* unit = figure.unit == eval::FigureUnit::kMicrometres ? " um"
                     : figure.unit == eval::FigureUnit::kDegrees   ? " deg"
                                                                   : "";
  return fmt::format("{:.{}f}{}", found->get<double>(), figure.decimals, unit);
}

int run_eval(const Context& context, const EvalCommandOptions& options) {
  eval::EvalOptions eval_options = options.eval;
  eval_options.voxel_size_m = options.voxel_um * 1e-6;
  eval_options.align_first_pose = !options.no_align;
  // With online deformation, `sls scan` leaves the model as tracked in RESULT/undeformed: the
  // same figures for it, at the result's voxel size (undeformed/ has no report.json).
  const eval::ResultEvaluation evaluation = eval::evaluate_with_undeformed(
      options.result, options.truth, eval_options, context.progress_callback("eval"));
  const eval::EvalReport& report = evaluation.report;

  nlohmann::json out = {{"ok", true}};
  out.update(eval::result_evaluation_json(evaluation));
  std::optional<nlohmann::json> undeformed;
  if (evaluation.undeformed) undeformed = out["undeformed"];
  std::optional<eval::ViewRegionErrors> regions;
  if (!options.raw_scan.empty()) {
    regions = eval::result_region_errors(report, options.raw_scan, options.raw_scan_frame);
    nlohmann::json json = {{"raw_scan", options.raw_scan},
                           {"frame", options.raw_scan_frame},
                           {"model_points", regions->model_points},
                           {"visible_points", regions->visible_points},
                           {"all", eval::region_json(regions->all)}};
    for (const eval::RegionErrors& region : regions->regions) json[region.name] = eval::region_json(region);
    out["regions"] = json;
  }

  context.emit(out, [&] {
    auto um = [](const eval::DistanceStats& stats, double eval::DistanceStats::*field) {
      return stats.count > 0 ? fmt::format("{:.2f} um", stats.*field * kUm) : std::string("n/a");
    };
    const eval::SurfaceErrors& e = report.cloud;
    std::cout << fmt::format("{} ({} points) against {} ({}), voxel {:.2f} um ({})\n", report.result_folder,
                             report.cloud_points, report.recording_folder, report.scene_name,
                             report.voxel_size_m * kUm, report.voxel_size_source);
    std::cout << fmt::format("c2c: mean {}, rms {}, p95 {}, max {}\n", um(e.all, &eval::DistanceStats::mean_m),
                             um(e.all, &eval::DistanceStats::rms_m), um(e.all, &eval::DistanceStats::p95_m),
                             um(e.all, &eval::DistanceStats::max_m));
    std::cout << fmt::format("edge c2c (within {:.1f} um of a crease): {}\n", report.edge_band_m * kUm,
                             e.has_creases ? fmt::format("mean {}, rms {} over {} points",
                                                         um(e.edge, &eval::DistanceStats::mean_m),
                                                         um(e.edge, &eval::DistanceStats::rms_m), e.edge.count)
                                           : std::string("n/a (the scene has no creases)"));
    if (report.mesh) {
      std::cout << fmt::format("mesh.ply vertices: c2c mean {}, edge mean {}\n",
                               um(report.mesh->all, &eval::DistanceStats::mean_m),
                               um(report.mesh->edge, &eval::DistanceStats::mean_m));
    }
    std::cout << fmt::format("coverage: {:.4f} ({} of {} {} reference points within {:.1f} um)\n",
                             report.coverage.fraction(), report.coverage.covered, report.coverage.considered,
                             report.coverage_basis == "visible" ? "visible" : "in-region",
                             report.coverage_radius_m * kUm);
    if (report.trajectory) {
      const eval::TrajectoryErrors& t = *report.trajectory;
      std::cout << fmt::format("trajectory: ATE rmse {:.2f} um, max {:.2f} um over {} frames{}\n", t.ate_rmse_m * kUm,
                               t.ate_max_m * kUm, t.matched_frames,
                               t.unmatched_frames > 0 ? fmt::format(" ({} without a true pose)", t.unmatched_frames)
                                                      : std::string());
      std::cout << fmt::format("loop closure (first to last frame, {:.3f} s to {:.3f} s): {:.2f} um, {:.4f} deg\n",
                               t.first_timestamp_s, t.last_timestamp_s, t.loop_closure_error_m * kUm,
                               t.loop_closure_error_rad * 180.0 / M_PI);
    } else {
      std::cout << fmt::format("trajectory: n/a ({})\n", report.trajectory_note);
    }
    if (report.alignment != "none") {
      std::cout << fmt::format("aligned by the first pose: {:.2f} um, {:.4f} deg\n",
                               report.T_object_world.translation().norm() * kUm,
                               report.T_object_world.angle_rad() * 180.0 / M_PI);
    }
    if (regions) {
      std::cout << fmt::format("\nC2C in the four quadrants of frame {}'s view ({} of {} points seen), against its "
                               "raw scan {} and the exact surface:\n",
                               options.raw_scan_frame, regions->visible_points, regions->model_points, options.raw_scan);
      std::cout << fmt::format("  {:<14}{:>10}{:>18}{:>18}\n", "region", "points", "to raw scan", "to surface");
      auto row = [&](const eval::RegionErrors& region) {
        std::cout << fmt::format("  {:<14}{:>10}{:>18}{:>18}\n", region.name, region.to_raw_scan.count,
                                 um(region.to_raw_scan, &eval::DistanceStats::mean_m),
                                 um(region.to_surface, &eval::DistanceStats::mean_m));
      };
      for (const eval::RegionErrors& region : regions->regions) row(region);
      row(regions->all);
    }
    if (undeformed) {
      std::cout << fmt::format("\nonline deformation: {} (deformed) beside {} (as tracked, {} points), voxel {:.2f} um\n",
                               report.result_folder, evaluation.undeformed->result_folder, (*undeformed)["points"].get<std::size_t>(),
                               report.voxel_size_m * kUm);
      std::cout << fmt::format("  {:<20}{:>16}{:>16}\n", "", "deformed", "as tracked");
      for (const eval::SideBySideFigure& figure : eval::kSideBySideFigures) {
        std::cout << fmt::format("  {:<20}{:>16}{:>16}\n", figure.label, figure_text(out, figure),
                                 figure_text(*undeformed, figure));
      }
    }
  });
  return kExitOk;
}

}  // namespace

void add_eval_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "eval", "Measure a fused result against a simulated recording: C2C, edge-region C2C, coverage, ATE, loop "
      "closure (in um); with RESULT/undeformed (online deformation), the model as tracked beside it");
  auto options = std::make_shared<EvalCommandOptions>();
  command->add_option("--result", options->result,
                      "Result folder (cloud.ply; mesh.ply, report.json, trajectory.txt optional). When it holds "
                      "undeformed/cloud.ply (and trajectory.txt: sls scan with online deformation writes the model "
                      "as tracked there), that is measured too, at the result's voxel size, and printed side by side "
                      "(\"deformed\" / \"as tracked\"; --json: an \"undeformed\" object with the same keys)")
      ->required();
  command->add_option("--truth", options->truth, "The simulated recording it was made from (with groundtruth/)")
      ->required();
  command->add_option("--voxel-um", options->voxel_um,
                      "Voxel size in um (default: voxel_size_m of RESULT/report.json)")
      ->check(CLI::PositiveNumber);
  command->add_option("--edge-band-voxels", options->eval.edge_band_voxels,
                      "Edge region: points this many voxels from a crease")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--coverage-radius-voxels", options->eval.coverage_radius_voxels,
                      "A reference point is covered by an output point this close")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--visibility-stride", options->eval.visibility_stride,
                      "Test every n-th frame for which reference points the recording saw")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_flag("--register", options->eval.register_to_surface,
                    "Then register the model rigidly onto the exact surface before measuring: the shape's error "
                    "alone, whatever frame the calibration defines (as CloudCompare's fine registration)");
  command->add_flag("--no-align", options->no_align,
                    "Do not align RESULT/trajectory.txt's first pose to the true one (compare as written)");
  command->add_option("--raw-scan", options->raw_scan,
                      "The paper's Table I: also the C2C mean in the four image quadrants of one view against that "
                      "view's raw scan (its depth map, e.g. frames/NNNNNN/depth.pfm of `sls decode`, registered by "
                      "the result's pose of the view) and against the exact surface");
  command->add_option("--raw-scan-frame", options->raw_scan_frame, "With --raw-scan: the recording frame it is of")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  command->callback([&context, exit_code, options] {
    run_command(context, "eval", [&context, options] { return run_eval(context, *options); }, exit_code);
  });
}

}  // namespace sls::cli
