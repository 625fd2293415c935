// Pattern families beyond slscan's own (pattern_set.h), and the description file that names a
// family and its parameters so that a capture made elsewhere can be decoded without code
// (format: sdk/decode/README.md; shipped examples: samples/patterns/).
//
// Every family here is a list of PatternDesc (pattern_shared.h) and decodes through the one
// Gray code + phase layout (decoder.h, decode_shared.h): CPU and CUDA alike.
#pragma once

#include <string>
#include <vector>

#include "sdk/decode/pattern_set.h"

namespace sls {

// Where white and black go in the stack.
enum class ReferencePlacement { kNone, kFirst, kLast };

// Gray code alone, over projector pixels: integer coordinates.
//  - OpenCV structured_light GrayCodePattern's order: per axis (columns, then rows) the bits
//    coarsest first, each pattern then its inverse; white and black last
//    (= make_opencv_graycode_pattern_set).
//  - slscan's order: white and black first, then the same.
// Without inverses each bit is thresholded against (white + black) / 2.
struct GrayCodeOptions {
  int projector_width = 1024;
  int projector_height = 768;
  bool columns = true;
  bool rows = true;
  bool inverse = true;
  ReferencePlacement references = ReferencePlacement::kLast;
  std::string name;  // empty: generated
};

enum class PhaseUnwrap {
  kGray,               // a Gray code numbering the coarsest period (stripes of P)
  kComplementaryGray,  // one more bit: stripes of P/2 whose edges fall mid-period (Zhang 2012)
  kNone,               // the coarsest period spans the axis: a one-period phase cue
};

// N-step phase shift at one or more periods per axis, unwrapped coarse to fine: the
// coarsest by the Gray code (or alone), each finer one by the coarser coordinate.
// Order: [white, black], then per axis (columns, then rows) the Gray bits coarsest first
// (each followed by its inverse when projected), then per period (coarsest first) the
// steps in step_order.
struct PhaseShiftOptions {
  int projector_width = 912;
  int projector_height = 1140;
  bool columns = true;
  bool rows = false;
  int steps = 4;                     // N >= 3
  std::vector<int> step_order;       // the order the steps are projected; empty: 0 .. N-1
  std::vector<double> periods_px{16.0};    // columns; any order, distinct, need not be integers
  std::vector<double> row_periods_px;      // rows; empty: periods_px
  bool reversed = false;             // phase sign (PatternDesc::phase_reversed)
  double offset_rad = 0.0;
  PhaseUnwrap unwrap = PhaseUnwrap::kComplementaryGray;
  bool gray_inverse = true;          // Gray patterns followed by their complements
  double gray_shift_px = 0.0;        // >= 0: the Gray stripes start this far left of pixel 0
  bool references = true;            // white and black first
  GrayThresholdMode gray_threshold = GrayThresholdMode::kAuto;
  std::string name;
};

// Throw sls::Error(kInvalidArgument) naming the bad option.
PatternSet make_gray_code_pattern_set(const GrayCodeOptions& options);
PatternSet make_phase_shift_pattern_set(const PhaseShiftOptions& options);

// A pattern-set description (JSON, sdk/decode/README.md): either the explicit pattern list
// of pattern_set_to_json, or {"family": ..., parameters}. Throws sls::Error: kFormat (not
// JSON, missing or mistyped fields, unknown names), kInvalidArgument (unusable values).
PatternSet pattern_set_from_description(const std::string& json);
// The same from a file; errors name the file.
PatternSet load_pattern_description(const std::string& path);

}  // namespace sls
