// sls import: captures made by another system (a folder of PNG/BMP/TIFF pattern stacks, a
// pattern description, a calibration in OpenCV YAML/XML) into an ordinary recording that
// `sls decode` and `sls scan` take (calib/capture_import.h; docs/import.md).
#include <iostream>
#include <memory>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "samples/sls/commands.h"
#include "sdk/core/error.h"
#include "sdk/decode/pattern_families.h"

#if defined(SLS_HAVE_CALIB)
#include "calib/capture_import.h"
#endif

namespace sls::cli {
namespace {

struct ImportCommandOptions {
  std::string images;
  std::string patterns;
  std::string calibration;
  std::string out;
  std::string name_pattern;
  double unit_mm = 1.0;
  int bit_depth = 0;
  bool no_check = false;
};

#if defined(SLS_HAVE_CALIB)
int run_import(const Context& context, const ImportCommandOptions& options) {
  calib::CaptureImportOptions o;
  o.images = options.images;
  o.name_pattern = options.name_pattern;
  o.patterns = load_pattern_description(options.patterns);
  o.calibration = options.calibration;
  o.unit_m = options.unit_mm * 1e-3;
  o.bit_depth = options.bit_depth;
  o.out = options.out;
  o.check = !options.no_check;
  const calib::CaptureImportSummary summary = calib::import_capture(o, context.progress_callback("import"));
  nlohmann::json result = {{"ok", true},
                           {"recording", options.out},
                           {"frames", summary.frames},
                           {"images_per_frame", summary.images_per_frame},
                           {"camera", {summary.width, summary.height}},
                           {"bit_depth", summary.bit_depth},
                           {"pattern_set", o.patterns.name},
                           {"pattern_kind", pattern_set_kind_name(o.patterns.kind)},
                           {"calibration_layout", summary.calibration_layout},
                           {"stacks", summary.stacks},
                           {"skipped", summary.skipped}};
  if (summary.checked_fraction >= 0.0) result["checked_decoded_fraction"] = summary.checked_fraction;
  context.emit(result, [&] {
    std::cout << fmt::format("imported {} frame(s) of {} images ({}x{}, {}-bit, pattern set '{}') into {}",
                             summary.frames, summary.images_per_frame, summary.width, summary.height,
                             summary.bit_depth, o.patterns.name, options.out);
    if (summary.checked_fraction >= 0.0) {
      std::cout << fmt::format("; {:.1f} % of the first stack's pixels decode", 100.0 * summary.checked_fraction);
    }
    std::cout << "\ncalibration keys: " << summary.calibration_layout << "\n";
    for (const std::string& folder : summary.skipped) {
      std::cout << "left out " << folder << ": images of the projector's size (the patterns themselves?)\n";
    }
  });
  return kExitOk;
}
#endif

}  // namespace

void add_import_command(CLI::App& app, Context& context, int* exit_code) {
  CLI::App* command = app.add_subcommand(
      "import", "Turn captures made by another system (image stacks, a pattern description, an OpenCV calibration) "
                "into a recording that sls decode and sls scan take");
  auto options = std::make_shared<ImportCommandOptions>();
  command
      ->add_option("--images", options->images,
                   "Folder of 8/16-bit PNG, BMP or TIFF images: one pattern stack per subfolder (sorted by name), or "
                   "the folder itself as one stack, or files named by --name-pattern")
      ->required();
  command
      ->add_option("--patterns", options->patterns,
                   "Pattern description (JSON: the family, its parameters, the image order, projector size and "
                   "direction; sdk/decode/README.md, examples in samples/patterns/)")
      ->required();
  command
      ->add_option("--calibration", options->calibration,
                   "Calibration in OpenCV YAML/XML (camera and projector K, distortion, R and T from camera to "
                   "projector: docs/import.md lists the keys read) or slscan's calibration.yml")
      ->required();
  command->add_option("--out", options->out, "Recording folder to create (must not exist or be empty)")->required();
  command->add_option("--name-pattern", options->name_pattern,
                      "File names (relative to --images) with {frame} and {image} for numbers and * for any text, "
                      "e.g. \"scan{frame}/img_{image}.bmp\"; default: one stack per subfolder");
  command->add_option("--unit-mm", options->unit_mm, "Millimetres per length unit of the calibration's translation")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  command->add_option("--bit-depth", options->bit_depth,
                      "Bits used by 16-bit images (10, 12, 14 or 16; 0: 16); 8-bit images are 8")
      ->check(CLI::IsMember({0, 10, 12, 14, 16}))
      ->capture_default_str();
  command->add_flag("--no-check", options->no_check,
                    "Do not decode the first stack to check that the description fits the images");
  command->callback([&context, exit_code, options] {
    run_command(context, "import",
                [&context, options] {
#if defined(SLS_HAVE_CALIB)
                  return run_import(context, *options);
#else
                  (void)context;
                  throw_error(ErrorCode::kUnsupported, "sls was built without OpenCV: import is not available");
                  return kExitUnavailable;
#endif
                },
                exit_code);
  });
}

}  // namespace sls::cli
