// Pattern families beyond slscan's own (pattern_set.h), and the description file that names a
// family and its parameters so that a capture made elsewhere can be decoded without code
// (format: sdk/decode/README.md; shipped examples: samples/patterns/).
//
// Every family here is a list of PatternDesc (pattern_shared.h) and decodes through one layout
// (decoder.h): Gray code + phase (decode_shared.h), or heterodyne and micro phase shifting
// (multi_frequency_shared.h), CPU and CUDA alike.
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
  kHeterodyne,         // no Gray code: 2 or 3 periods whose beat spans the axis (set kind kHeterodyne)
};

// N-step phase shift at one or more periods per axis, unwrapped coarse to fine: the
// coarsest by the Gray code (or alone), each finer one by the coarser coordinate; or, with
// PhaseUnwrap::kHeterodyne, by the beats of two or three periods (multi-frequency temporal
// unwrapping: the classic three periods are W/70, W/64 and W/59 of a width W at least the
// axis', whose beats are W/6, W/5 and W).
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

// Micro phase shifting (Gupta & Nayar, CVPR 2012): an N-step phase shift of the first
// period, then one image (step 0) of each other period, all in a narrow band so that defocus
// and inter-reflections attenuate them alike; the decoder searches the first period's
// periods for the one the single images agree with (multi_frequency_shared.h). F periods take
// N + F - 1 images per axis. Order: [white, black], then per axis (columns, then rows) the N
// steps in step order, then the other periods in the order given.
struct MicroPhaseOptions {
  int projector_width = 912;
  int projector_height = 1140;
  bool columns = true;
  bool rows = false;
  int steps = 3;                    // N >= 3 of the first period
  // The first takes the N steps. Default: six periods within 16..19 px chosen for the DLP4500's
  // 912 columns (their candidates' cosine vectors are >= 0.41 apart; docs in sdk/decode/README.md).
  std::vector<double> periods_px{19.0, 17.77, 17.3, 17.15, 16.0, 17.59};
  std::vector<double> row_periods_px;  // rows; empty: periods_px
  bool reversed = false;
  double offset_rad = 0.0;
  bool references = true;           // white and black first
  std::string name;
};

// Throw sls::Error(kInvalidArgument) naming the bad option (for heterodyne and micro phase
// shifting also periods that cannot number the axis: decoder.h's make_decode_layout).
PatternSet make_gray_code_pattern_set(const GrayCodeOptions& options);
PatternSet make_phase_shift_pattern_set(const PhaseShiftOptions& options);
PatternSet make_micro_phase_pattern_set(const MicroPhaseOptions& options);

// A pattern-set description (JSON, sdk/decode/README.md): either the explicit pattern list
// of pattern_set_to_json, or {"family": ..., parameters}. Throws sls::Error: kFormat (not
// JSON, missing or mistyped fields, unknown names), kInvalidArgument (unusable values).
PatternSet pattern_set_from_description(const std::string& json);
// The same from a file; errors name the file.
PatternSet load_pattern_description(const std::string& path);

}  // namespace sls
