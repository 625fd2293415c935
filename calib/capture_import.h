// Captures made by other systems into an ordinary slscan recording (`sls import`,
// docs/import.md): a folder of 8/16-bit PNG, BMP or TIFF images (one pattern stack per
// subfolder, the folder itself as one stack, or files named by a pattern), a pattern
// description (sdk/decode/pattern_families.h) and a calibration in OpenCV YAML/XML
// (opencv_calibration_import.h). In calib/ because it reads BMP/TIFF and FileStorage through
// OpenCV, which stays in this folder.
#pragma once

#include <string>
#include <vector>

#include "calib/opencv_calibration_import.h"
#include "sdk/core/progress.h"
#include "sdk/decode/pattern_set.h"

namespace sls::calib {

struct CaptureImportOptions {
  std::string images;        // the folder of captures
  // Empty: each subfolder (sorted by name, numbers in names compared as numbers) is a stack
  // of its image files in name order; without subfolders the folder is one stack. Otherwise
  // file names (relative to `images`, '/' between folders) matching it, with {frame} and
  // {image} standing for decimal numbers (the stack and the image's place in it) and '*' for
  // any text, e.g. "scan{frame}/img_{image}.bmp" or "f{frame}_*_{image}.tif".
  std::string name_pattern;
  PatternSet patterns;
  std::string calibration;   // OpenCV YAML/XML (or slscan's calibration.yml)
  double unit_m = 1e-3;      // metres per length unit of the calibration's translation
  int bit_depth = 0;         // of 16-bit images (10, 12, 14, 16); 0: 16. 8-bit images are 8
  std::string out;           // the recording folder to create (must not exist or be empty)
  bool check = true;         // decode the first stack to check that the description fits the images
};

struct CaptureImportSummary {
  int frames = 0;
  int images_per_frame = 0;
  int width = 0;
  int height = 0;
  int bit_depth = 0;
  std::string calibration_layout;  // the calibration file's keys used
  std::vector<std::string> stacks;  // each frame's source folder
  // Folders left out: stacks of the projector's size among captures of another size (the
  // patterns themselves, saved beside the captures by some tools).
  std::vector<std::string> skipped;
  double checked_fraction = -1.0;   // share of the first stack's pixels that decoded; -1: not checked
};

// The stacks the options name (image paths in stack order), without reading any image.
// Throws sls::Error(kNotFound) for no images, kInvalidArgument for a stack whose image count
// differs from the pattern description's (naming the stack and both counts).
std::vector<std::vector<std::string>> find_capture_stacks(const CaptureImportOptions& options);

// Writes the recording. Throws sls::Error naming the file and the problem: a wrong image
// count, images of mixed sizes or bit depths, an unreadable image or calibration, a
// calibration of another camera or projector size, a description that does not match the
// images (the first stack does not behave as it says, or nothing of it decodes).
CaptureImportSummary import_capture(const CaptureImportOptions& options, const ProgressCallback& progress = {});

}  // namespace sls::calib
