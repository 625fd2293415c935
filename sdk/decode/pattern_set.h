// Pattern sets: the ordered list of patterns one scan frame projects, as the projector
// driver loads them (DLPC350 8-bit pattern sequence), the simulator renders them, the
// recording manifest names them ("pattern_set") and the decoder reads them.
//
// The default set (make_gray_phase_pattern_set with default options), for the default rig
// of docs/simulator-optics.md (DLP4500, 912 x 1140):
//   white, black,
//   Gray code over the columns, bits 9..4, each followed by its inverse (12 patterns),
//   8-step phase shift of period 32 columns (8 patterns)            = 22 images per frame.
// Why these numbers:
//  - Period 32 px is 0.56 mm on the object. That keeps the fringe modulation >= 50 % over the
//    +-5 mm usable depth of field at f/8 (docs/simulator-optics.md shows the numbers); a
//    shorter period would need a smaller aperture, a longer one gives up precision (the
//    coordinate error is P/(2*pi) times the phase error).
//  - Gray bits >= 5 number the 29 periods (k >> 5); bit 4 (32 px stripes, edges in the
//    middle of each period) is the extra "complementary" bit that lets the decoder fix
//    period-boundary unwrapping errors. Finer bits add nothing the phase does not give, and
//    bits 0..2 (stripes of 2..8 px) keep 50 % contrast only within +-0.6..2.6 mm of focus, so
//    the default stops at bit 4; gray_lowest_bit = 0 gives a full-resolution code.
//  - 8 steps rather than 4: N-step phase shifting is blind to intensity harmonics up to
//    order N - 2, so the DMD's 8-bit quantisation and any camera non-linearity bias the phase
//    far less, and the phase noise sqrt(2/N) * sigma_I / B is 1/sqrt(2) that of 4 steps, for
//    4 more images, which a 3 Hz frame rate affords (22 images at the DLPC350's 120 Hz
//    8-bit pattern rate take 0.18 s).
//  - Inverse Gray patterns make each bit's decision a comparison of two images (robust to
//    albedo, ambient light and blur, which moves no edge of a complementary pair).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "sdk/core/image.h"
#include "sdk/decode/pattern_shared.h"

namespace sls {

// What kind of set it is: the family it was made as (pattern_families.h), so tools can
// name it, and for the last two how the decoder unwraps it (decoder.h: the Gray-code and
// phase-shift kinds by their Gray code, heterodyne and micro phase shifting by their periods).
enum class PatternSetKind : std::int32_t {
  kGrayPhase = 0,   // slscan's own: Gray code over pixels down to the complementary bit + phase
  kHeterodyne = 1,  // N-step phase shift at 2-3 periods unwrapped by their beats, no Gray code
  kGrayCode = 2,    // Gray code alone (OpenCV structured_light's order, or ours)
  kPhaseShift = 3,  // N-step phase shift at one or more periods, Gray / complementary Gray unwrapped
  kMicroPhase = 4,  // micro phase shifting: one N-step period + one image of each nearby period
};

// How Gray patterns without a projected complement are thresholded.
enum class GrayThresholdMode : std::int32_t {
  kAuto = 0,        // against (white + black) / 2 when the set has both, else the phase mean
  kWhiteBlack = 1,  // against (white + black) / 2
  kPhaseMean = 2,   // against the mean of the axis' (coarsest) phase images
};

struct PatternSet {
  std::string name;
  PatternSetKind kind = PatternSetKind::kGrayPhase;
  int projector_width = 0;   // DMD columns
  int projector_height = 0;  // DMD rows
  GrayThresholdMode gray_threshold = GrayThresholdMode::kAuto;
  std::vector<PatternDesc> patterns;

  std::size_t size() const { return patterns.size(); }
  bool operator==(const PatternSet& other) const {
    return name == other.name && kind == other.kind && projector_width == other.projector_width &&
           projector_height == other.projector_height && gray_threshold == other.gray_threshold &&
           patterns == other.patterns;
  }
  bool operator!=(const PatternSet& other) const { return !(*this == other); }
};

struct GrayPhaseOptions {
  int projector_width = 912;    // DLP4500 / DLPC350 native pattern size
  int projector_height = 1140;
  bool columns = true;          // encode columns (the triangulation axis of the default rig)
  bool rows = false;            // also encode rows
  int phase_steps = 8;          // N >= 3
  int phase_period_px = 32;     // P >= 3, columns
  int row_phase_period_px = 0;  // rows; 0 = phase_period_px (in row pixels: on the diamond
                                // DMD rows are half the column pitch, so 2*P gives the same
                                // fringe pitch on the object)
  // Finest Gray bit projected: -1 = automatic, floor(log2(P)) - 1 (period number plus the
  // complementary half-period bit); 0 = full resolution (every pixel its own code).
  int gray_lowest_bit = -1;
  bool inverse_gray = true;  // each Gray pattern followed by its complement
  bool references = true;    // white and black first
  std::string name;          // empty: generated from the parameters
};

// Builds the set. Order: [white, black], then per axis (columns, then rows): Gray bits from
// the coarsest down, each followed by its inverse, then the phase steps j = 0..N-1.
// Throws sls::Error(kInvalidArgument) for unusable options.
PatternSet make_gray_phase_pattern_set(const GrayPhaseOptions& options = {});

// OpenCV structured_light GrayCodePattern's order for a width x height projector (what its
// users and tools such as procam-calibration capture): per column bit, coarsest first, the
// pattern then its inverse; the same for the rows; then (with references) white and black
// last. Gray code only: coordinates are integers.
PatternSet make_opencv_graycode_pattern_set(int width, int height, bool references = true);

// A built-in set by name, for captures made elsewhere (`sls calibrate --patterns`):
//   "opencv-graycode:WxH"   make_opencv_graycode_pattern_set(W, H)
//   "gray-phase:WxH"        make_gray_phase_pattern_set with columns and rows, W x H
// Throws sls::Error(kInvalidArgument) naming the name and the names known.
PatternSet pattern_set_from_name(const std::string& name);

// Bits a Gray code needs to give each of `extent` pixels its own code: ceil(log2(extent)).
int gray_code_bits(int extent);
// Bits a Gray code over stripes (PatternDesc::gray_unit_px, gray_origin_px) needs to number
// every stripe that a pixel of [0, extent) falls in.
int gray_code_bits(const PatternDesc& gray_pattern);

// Names of the set kinds in JSON ("gray_phase", "gray_code", "phase_shift", ...).
const char* pattern_set_kind_name(PatternSetKind kind);

// The finest Gray bit the automatic choice projects for a phase period (see
// GrayPhaseOptions::gray_lowest_bit).
int automatic_gray_lowest_bit(int phase_period_px);

// Checks sizes, that every descriptor's extent matches its axis, bit ranges, steps and
// periods. Throws sls::Error(kInvalidArgument) naming the first bad pattern.
void validate_pattern_set(const PatternSet& set);

// A short label for logs and file names: "white", "black", "gray_c9", "gray_c9_inv",
// "phase_c_p32_s3of8" (c = columns, r = rows).
std::string pattern_label(const PatternDesc& pattern);

// JSON (one object) for the recording manifest's "pattern_set" field:
//   {"format": "slscan-pattern-set", "format_version": 1, "name": ..., "kind": "gray_phase",
//    "projector": {"width": 912, "height": 1140}, "image_count": 22,
//    "patterns": [{"kind": "white"}, {"kind": "black"},
//                 {"kind": "gray_code", "axis": "columns", "bit": 9, "inverted": false},
//                 {"kind": "phase_shift", "axis": "columns", "step": 0, "steps": 8,
//                  "period_px": 32}, ...]}
// Extents are not stored: they follow from the axis and the projector size. Fields other
// tools need are written only when they differ from slscan's defaults (then format_version
// 2): "period_px" not an integer, "reversed": true, "offset_rad", Gray "unit_px" and
// "origin_px", the set's "gray_threshold" ("white_black" | "phase_mean"). Version-1 files
// read as before. The description files of sdk/decode/README.md add a family form
// (pattern_families.h).
std::string pattern_set_to_json(const PatternSet& set);
// Parses and validates. Throws sls::Error: kFormat (not JSON, missing or mistyped fields,
// unknown kinds), kVersionMismatch (a newer format_version), kInvalidArgument (validation).
PatternSet pattern_set_from_json(const std::string& json);

// The levels of a pattern along its axis (extent bytes): the table that
// pattern_value_blurred(PatternLevelTable, ...) reads.
std::vector<std::uint8_t> pattern_levels(const PatternDesc& pattern);

// The full DMD image of a pattern (width x height, e.g. for a DLPC350 pattern image or the
// docs): pixel (x, y) = pattern_pixel_value(pattern, x) for column patterns and
// pattern_pixel_value(pattern, y) for row patterns.
Image8u rasterize_pattern(const PatternDesc& pattern, int width, int height);
Image8u rasterize_pattern(const PatternSet& set, std::size_t index);

}  // namespace sls
