// The pattern families of issue 21 (sdk/decode/pattern_families.h): their levels, their JSON
// (explicit lists with the new fields, description files), and each description shipped in
// samples/patterns/ rendered by the simulator on a plane, noise-free, decoded on the CPU and
// checked against the ground truth.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "sdk/core/error.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/multi_frequency_layout.h"
#include "sdk/decode/pattern_families.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

std::string sample(const std::string& name) { return std::string(SLS_SOURCE_DIR) + "/samples/patterns/" + name; }

ErrorCode error_code_of(const std::string& json) {
  try {
    pattern_set_from_description(json);
  } catch (const Error& error) {
    return error.code();
  }
  return ErrorCode::kInternal;  // no error: a value no check expects
}

TEST(PatternFamilies, PhaseLevelsFollowSignOffsetAndFractionalPeriods) {
  PatternDesc d;
  d.kind = PatternKind::kPhaseShift;
  d.extent = 200;
  d.steps = 4;
  d.step = 1;
  d.period_px = 22.8;
  for (int k = 0; k < 200; ++k) {
    const double angle = 2.0 * M_PI * (k / 22.8 + 0.25);
    EXPECT_NEAR(pattern_pixel_value(d, k), 127.5 + 127.5 * std::cos(angle), 0.5 + 1e-9) << k;
  }
  // Reversed: cos(-2 pi k / P + 2 pi j / N), exact integer path for an integer period.
  PatternDesc r = d;
  r.period_px = 32;
  r.phase_reversed = true;
  PatternDesc offset = r;
  offset.phase_reversed = false;
  for (int k = 0; k < 64; ++k) {
    const double angle = 2.0 * M_PI * (-k / 32.0 + 0.25);
    EXPECT_NEAR(pattern_pixel_value(r, k), 127.5 + 127.5 * std::cos(angle), 0.5 + 1e-9) << k;
  }
  offset.phase_offset_rad = 0.5;
  for (int k = 0; k < 64; ++k) {
    const double angle = 2.0 * M_PI * (k / 32.0 + 0.25) + 0.5;
    EXPECT_NEAR(pattern_pixel_value(offset, k), 127.5 + 127.5 * std::cos(angle), 0.5 + 1e-9) << k;
  }
}

TEST(PatternFamilies, GrayCodeOverStripes) {
  PatternDesc d;
  d.kind = PatternKind::kGrayCode;
  d.extent = 100;
  d.gray_unit_px = 11.4;  // half of a 22.8 px period
  d.gray_origin_px = -3.0;
  EXPECT_EQ(gray_code_bits(d), 4);  // stripes 0 .. floor((99.5 + 3) / 11.4) = 8
  for (int k = 0; k < 100; ++k) {
    const auto stripe = static_cast<std::uint32_t>(std::floor((k + 0.5 + 3.0) / 11.4));
    for (int bit = 0; bit < 4; ++bit) {
      d.bit = bit;
      EXPECT_EQ(pattern_pixel_value(d, k), ((gray_encode(stripe) >> bit) & 1u) != 0u ? 255 : 0) << k << " " << bit;
    }
  }
}

TEST(PatternFamilies, JsonCarriesTheNewFieldsAndKeepsVersion1ForOurOwn) {
  const PatternSet own = make_gray_phase_pattern_set();
  EXPECT_NE(pattern_set_to_json(own).find("\"format_version\":1"), std::string::npos);
  PhaseShiftOptions o;
  o.periods_px = {96.0, 22.8};
  o.reversed = true;
  o.offset_rad = 0.25;
  o.gray_shift_px = 2.5;
  o.gray_inverse = false;
  o.gray_threshold = GrayThresholdMode::kPhaseMean;
  o.rows = true;
  o.row_periods_px = {100.0};
  o.unwrap = PhaseUnwrap::kGray;
  const PatternSet set = make_phase_shift_pattern_set(o);
  const std::string json = pattern_set_to_json(set);
  EXPECT_NE(json.find("\"format_version\":2"), std::string::npos) << json;
  EXPECT_NE(json.find("\"period_px\":22.8"), std::string::npos) << json;
  EXPECT_NE(json.find("\"reversed\":true"), std::string::npos) << json;
  EXPECT_NE(json.find("\"origin_px\":-2.5"), std::string::npos) << json;
  EXPECT_NE(json.find("\"gray_threshold\":\"phase_mean\""), std::string::npos) << json;
  EXPECT_EQ(pattern_set_from_json(json), set);
  EXPECT_EQ(pattern_set_from_description(json), set);  // an explicit list is a description too
  EXPECT_EQ(set.kind, PatternSetKind::kPhaseShift);
}

TEST(PatternFamilies, DescriptionsNameAFamilyAndItsParameters) {
  // No family: slscan's own, at the default DMD.
  EXPECT_EQ(pattern_set_from_description("{}").patterns, make_gray_phase_pattern_set().patterns);
  const PatternSet opencv = load_pattern_description(sample("opencv_graycode_1024x768.json"));
  EXPECT_EQ(opencv.patterns, make_opencv_graycode_pattern_set(1024, 768).patterns);
  EXPECT_EQ(opencv.size(), 42u);
  const PatternSet own = load_pattern_description(sample("slscan_gray_phase.json"));
  EXPECT_EQ(own.patterns, make_gray_phase_pattern_set().patterns);
  const PatternSet complementary = load_pattern_description(sample("complementary_gray_phase_shift.json"));
  EXPECT_EQ(complementary.size(), 2u + 2u * 7u + 4u);
  const PatternSet multi = load_pattern_description(sample("multi_period_gray_phase_shift.json"));
  EXPECT_EQ(multi.size(), 2u + 2u * 4u + 15u);
  for (const PatternSet* set : {&opencv, &own, &complementary, &multi}) EXPECT_NO_THROW(make_decode_layout(*set));

  // Typos and nonsense are errors that say what is wrong.
  EXPECT_EQ(error_code_of("{\"family\":\"phase_shift\",\"period\":12}"), ErrorCode::kFormat);
  EXPECT_EQ(error_code_of("{\"family\":\"sawtooth\"}"), ErrorCode::kFormat);
  EXPECT_EQ(error_code_of("{\"family\":\"phase_shift\",\"steps\":2}"), ErrorCode::kInvalidArgument);
  EXPECT_EQ(error_code_of("{\"family\":\"phase_shift\",\"periods_px\":[64],\"unwrap\":\"none\"}"),
            ErrorCode::kInvalidArgument);
  EXPECT_EQ(error_code_of("{\"family\":\"phase_shift\",\"step_order\":[0,1,1,3]}"), ErrorCode::kInvalidArgument);
  EXPECT_EQ(error_code_of("{\"format_version\":3}"), ErrorCode::kVersionMismatch);
  EXPECT_EQ(error_code_of("not json"), ErrorCode::kFormat);
  try {
    load_pattern_description(sample("no_such_file.json"));
    ADD_FAILURE() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kNotFound);
  }
}

struct PlaneFigures {
  double rms_px = 0.0, max_px = 0.0;
  std::size_t compared = 0, truth_valid = 0, jumps = 0;
  std::size_t ok = 0;  // pixels decoded
  std::size_t low_modulation = 0, inconsistent = 0;  // truly valid pixels flagged so
  double valid_fraction() const { return static_cast<double>(ok) / static_cast<double>(truth_valid); }
};

// Renders `set` on the plane (ci preset, noise-free unless `noise`), decodes it on the CPU
// and compares both coded axes with the ground truth.
PlaneFigures decode_plane(const PatternSet& set, double jump_px, bool screw = false, bool noise = false) {
  const sim::Scene scene = screw ? sim::make_knurled_screw_scene() : sim::make_plane_scene();
  sim::RigOptions options;
  options.preset = "ci";
  options.camera_width = 400;
  options.noise = noise;
  sim::SimRig rig = sim::make_rig(options, scene);
  sim::use_pattern_set(rig, set);
  sim::Renderer renderer(rig, scene, Device::cpu());
  renderer.set_frame(0);
  std::vector<Image16u> stack;
  for (std::size_t k = 0; k < set.size(); ++k) stack.push_back(renderer.render_pattern(static_cast<int>(k)));
  const sim::GroundTruthFrame truth = renderer.ground_truth();
  DecodeOptions decode_options;
  decode_options.min_depth_m = 0.09;
  decode_options.max_depth_m = 0.11;
  Decoder decoder(set, rig.calibration(), Device::cpu(), decode_options);
  const DecodedFrame decoded = decoder.decode(stack);
  const DecodeLayout& layout = decoder.decode_params().layout;
  PlaneFigures f;
  double sum = 0.0;
  for (int y = 0; y < truth.valid.height(); ++y) {
    for (int x = 0; x < truth.valid.width(); ++x) {
      if (!truth.valid(x, y)) continue;
      ++f.truth_valid;
      if ((decoded.mask(x, y) & kDecodeLowModulation) != 0) ++f.low_modulation;
      if ((decoded.mask(x, y) & kDecodeInconsistent) != 0) ++f.inconsistent;
      if (decoded.mask(x, y) != kDecodeOk) continue;
      ++f.ok;
      for (int axis = 0; axis < 2; ++axis) {
        if (layout.axes[axis].extent <= 0) continue;
        const double error = axis == 0 ? decoded.projector_u(x, y) - truth.projector_u(x, y)
                                       : decoded.projector_v(x, y) - truth.projector_v(x, y);
        sum += error * error;
        f.max_px = std::max(f.max_px, std::fabs(error));
        if (std::fabs(error) > jump_px) ++f.jumps;
        ++f.compared;
      }
    }
  }
  f.rms_px = std::sqrt(sum / static_cast<double>(std::max<std::size_t>(f.compared, 1)));
  std::printf("[families] %s on the %s (ci 400x300, %s): %zu coordinates, valid %.3f, RMS %.4f px, "
              "max %.3f px, %zu beyond %.1f px; of %zu truly valid pixels %zu low modulation, %zu inconsistent\n",
              set.name.c_str(), screw ? "knurled screw" : "plane", noise ? "noisy" : "noise-free", f.compared,
              f.valid_fraction(), f.rms_px, f.max_px, f.jumps, jump_px, f.truth_valid, f.low_modulation,
              f.inconsistent);
  return f;
}

TEST(PatternFamilies, ShippedDescriptionsDecodeThePlaneAgainstGroundTruth) {
  struct Case {
    const char* file;
    bool phase;
  };
  for (const Case c : {Case{"slscan_gray_phase.json", true}, Case{"complementary_gray_phase_shift.json", true},
                       Case{"multi_period_gray_phase_shift.json", true}, Case{"opencv_graycode_1024x768.json", false}}) {
    SCOPED_TRACE(c.file);
    const PatternSet set = load_pattern_description(sample(c.file));
    // A period jump would be >= the finest period minus the noise; Gray code alone is
    // integer: half a pixel, plus one where blur decides an edge pixel's finest bit.
    const PlaneFigures f = decode_plane(set, c.phase ? 1.0 : 2.0);
    // Gray code alone loses the pixels whose finest bits blur below the noise (2 px stripes).
    EXPECT_GT(f.valid_fraction(), c.phase ? 0.95 : 0.7);
    EXPECT_EQ(f.jumps, 0u);
    if (c.phase) {
      EXPECT_LE(f.rms_px, 0.02);
    } else {
      EXPECT_LE(f.rms_px, 0.45);  // integer codes: ~0.29 px of quantisation per axis
    }
  }
}

// The knurled screw, noisy: creases and shadow borders blur two faces into one pixel (errors
// of a pixel or two there, as for the default family in test_decoder), but no pixel is moved
// by a period: every error stays below half the finest period.
TEST(PatternFamilies, ShippedPhaseDescriptionsHaveNoPeriodJumpsOnTheKnurledScrew) {
  for (const char* file : {"complementary_gray_phase_shift.json", "multi_period_gray_phase_shift.json"}) {
    SCOPED_TRACE(file);
    const PatternSet set = load_pattern_description(sample(file));
    double finest = 1e9;
    for (const PatternDesc& d : set.patterns) {
      if (d.kind == PatternKind::kPhaseShift) finest = std::min(finest, d.period_px);
    }
    const PlaneFigures f = decode_plane(set, 0.5 * finest, true, true);
    EXPECT_GT(f.valid_fraction(), 0.8);
    EXPECT_EQ(f.jumps, 0u);
  }
}

// The families' options in turn on the plane: rows, a reversed phase with an offset,
// steps out of order, shifted Gray stripes without inverses thresholded against the phase
// mean, no references, a one-period phase cue as the unwrapping reference.
TEST(PatternFamilies, PhaseShiftVariantsDecodeThePlane) {
  std::vector<PhaseShiftOptions> variants(5);
  variants[0].rows = true;
  variants[0].periods_px = {18.0};
  variants[0].row_periods_px = {36.0};
  variants[1].reversed = true;
  variants[1].offset_rad = 1.0;
  variants[1].periods_px = {20.5};
  variants[1].step_order = {2, 0, 3, 1};
  variants[2].gray_inverse = false;
  variants[2].gray_shift_px = 5.0;
  variants[2].references = false;
  variants[2].periods_px = {24.0};
  variants[2].unwrap = PhaseUnwrap::kGray;
  variants[3].unwrap = PhaseUnwrap::kNone;
  variants[3].steps = 6;
  variants[3].periods_px = {1000.0, 100.0, 16.0};
  variants[4].steps = 3;
  variants[4].periods_px = {30.0};
  variants[4].gray_inverse = false;
  for (std::size_t i = 0; i < variants.size(); ++i) {
    SCOPED_TRACE(i);
    const PlaneFigures f = decode_plane(make_phase_shift_pattern_set(variants[i]), 1.0);
    EXPECT_GT(f.valid_fraction(), 0.95);
    EXPECT_EQ(f.jumps, 0u);
    EXPECT_LE(f.rms_px, 0.02);
  }
}

// --- Heterodyne and micro phase shifting ---------------------------------------------------

std::string error_message_of(const std::string& json) {
  try {
    pattern_set_from_description(json);
  } catch (const Error& error) {
    return error.what();
  }
  return "no error";
}

TEST(PatternFamilies, HeterodyneAndMicroPhaseDescriptionsLoad) {
  const PatternSet heterodyne = load_pattern_description(sample("heterodyne_3freq.json"));
  EXPECT_EQ(heterodyne.kind, PatternSetKind::kHeterodyne);
  EXPECT_EQ(heterodyne.size(), 2u + 3u * 4u);
  const PatternSet micro = load_pattern_description(sample("micro_phase_shifting.json"));
  EXPECT_EQ(micro.kind, PatternSetKind::kMicroPhase);
  EXPECT_EQ(micro.size(), 2u + 3u + 5u);
  for (const PatternSet* set : {&heterodyne, &micro}) {
    const DecodeLayout layout = make_decode_layout(*set);
    EXPECT_EQ(layout.unwrap, set == &micro ? kUnwrapMicroPhase : kUnwrapHeterodyne);
    const std::string json = pattern_set_to_json(*set);  // the explicit form says the kind
    EXPECT_EQ(pattern_set_from_json(json), *set) << json;
  }
  const DecodeLayout layout = make_decode_layout(micro);
  EXPECT_EQ(layout.axes[0].micro_count, 5);
  EXPECT_EQ(layout.axes[0].phase[0].count, 3);
  // What the sample's comment and MicroPhaseOptions say of its periods.
  EXPECT_NEAR(detail::micro_phase_code_distance(layout.axes[0]), 0.41, 0.01);
  EXPECT_EQ(make_micro_phase_pattern_set({}).patterns, micro.patterns);
  // The heterodyne sample's beats: 166.7 and 200 px, and 1000 px across the 912 columns.
  const float periods[3] = {14.2857f, 15.625f, 16.9492f};
  const HeterodyneBeats beats = heterodyne_beats(periods, 3);
  EXPECT_NEAR(beats.intermediate_px, 1000.0 / 6.0, 0.05);
  EXPECT_NEAR(beats.spanning_px, 1000.0, 0.5);
}

TEST(PatternFamilies, BadHeterodyneAndMicroPhaseDescriptionsAreRefused) {
  struct Case {
    const char* json;
    ErrorCode code;
    const char* says;  // part of the message
  };
  const Case cases[] = {
      {R"({"family":"phase_shift","unwrap":"heterodyne","periods_px":[16]})", ErrorCode::kInvalidArgument,
       "beats two or three periods"},
      {R"({"family":"phase_shift","unwrap":"heterodyne","periods_px":[16,24]})", ErrorCode::kInvalidArgument,
       "beat of 48.0 px is shorter than the 912 columns"},
      {R"({"family":"phase_shift","unwrap":"heterodyne","periods_px":[12,16,24]})", ErrorCode::kInvalidArgument,
       "both pairs beat at 48 px"},
      {R"({"family":"phase_shift","unwrap":"heterodyne","direction":"both","periods_px":[14.2857,15.625,16.9492]})",
       ErrorCode::kInvalidArgument, "shorter than the 1140 rows"},
      {R"({"family":"phase_shift","unwrap":"heterodyne","periods_px":[20,21],"gray_inverse":false})",
       ErrorCode::kFormat, "\"gray_inverse\" has no meaning"},
      {R"({"family":"micro_phase","periods_px":[19]})", ErrorCode::kInvalidArgument, "1 periods (need 2..11)"},
      {R"({"family":"micro_phase","periods_px":[19,17,19]})", ErrorCode::kInvalidArgument, "listed twice"},
      {R"({"family":"micro_phase","periods_px":[16,32]})", ErrorCode::kInvalidArgument,
       "cannot tell the periods of 16 px apart"},
      {R"({"family":"micro_phase","steps":2})", ErrorCode::kInvalidArgument, "2 steps (need 3..32)"},
      {R"({"family":"micro_phase","projector":{"width":8192},"periods_px":[4,4.1]})", ErrorCode::kInvalidArgument,
       "2048 periods of 4 px along the 8192 columns; the search tries at most 1024"},
      {R"({"family":"micro_phase","unwrap":"gray"})", ErrorCode::kFormat, "has no parameter \"unwrap\""},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.json);
    EXPECT_EQ(error_code_of(c.json), c.code);
    EXPECT_NE(error_message_of(c.json).find(c.says), std::string::npos) << error_message_of(c.json);
  }
  // Explicit lists the layout refuses: a heterodyne set with a Gray code, a micro set whose
  // single-image period has two images.
  PhaseShiftOptions gray;
  gray.periods_px = {32.0};
  PatternSet with_gray = make_phase_shift_pattern_set(gray);
  with_gray.kind = PatternSetKind::kHeterodyne;
  EXPECT_THROW(make_decode_layout(with_gray), Error);
  PatternSet doubled = make_micro_phase_pattern_set({});
  doubled.patterns.push_back(doubled.patterns.back());
  doubled.patterns.back().step = 1;
  try {
    make_decode_layout(doubled);
    ADD_FAILURE() << "no error";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("both have several images"), std::string::npos) << error.what();
  }
}

// The largest error below half the finest period: a period jump moves a pixel by a whole one.
double half_finest_period(const PatternSet& set) {
  double finest = 1e9;
  for (const PatternDesc& d : set.patterns) {
    if (d.kind == PatternKind::kPhaseShift) finest = std::min(finest, d.period_px);
  }
  return 0.5 * finest;
}

// The shipped descriptions (columns), and rows alone with what other tools do differently:
// reversed phases with offsets, steps out of order, no references, two heterodyne frequencies,
// four micro steps. (Both axes at once: the CUDA comparison.)
std::vector<PatternSet> multi_frequency_variants() {
  std::vector<PatternSet> sets;
  sets.push_back(load_pattern_description(sample("heterodyne_3freq.json")));
  sets.push_back(load_pattern_description(sample("micro_phase_shifting.json")));
  // One beat of 1200 px over the 1140 rows, 20 periods of 60: the beat's noise is the
  // periods' amplified 20 x sqrt(2), which must stay under a tenth of the period.
  PhaseShiftOptions two;
  two.unwrap = PhaseUnwrap::kHeterodyne;
  two.columns = false;
  two.rows = true;
  two.steps = 5;
  two.step_order = {4, 2, 0, 3, 1};
  two.periods_px = {60.0, 1200.0 / 19.0};
  two.reversed = true;
  two.offset_rad = 0.8;
  two.references = false;
  sets.push_back(make_phase_shift_pattern_set(two));
  MicroPhaseOptions micro;
  micro.columns = false;
  micro.rows = true;
  micro.steps = 4;
  micro.reversed = true;
  micro.offset_rad = -0.4;
  micro.references = false;
  micro.periods_px = {23.75, 22.2125, 21.625, 21.4375, 20.0, 21.9875};  // the columns' x 1140/912
  sets.push_back(make_micro_phase_pattern_set(micro));
  return sets;
}

TEST(PatternFamilies, HeterodyneAndMicroPhaseDecodeThePlane) {
  for (const PatternSet& set : multi_frequency_variants()) {
    SCOPED_TRACE(set.name);
    const PlaneFigures f = decode_plane(set, half_finest_period(set));
    EXPECT_GT(f.valid_fraction(), 0.95);
    EXPECT_EQ(f.jumps, 0u);
    EXPECT_LE(f.rms_px, 0.02);
  }
}

// The knurled screw, noisy: no pixel moved by a period (errors below half the finest period).
TEST(PatternFamilies, HeterodyneAndMicroPhaseHaveNoPeriodJumpsOnTheKnurledScrew) {
  for (const char* file : {"heterodyne_3freq.json", "micro_phase_shifting.json"}) {
    SCOPED_TRACE(file);
    const PatternSet set = load_pattern_description(sample(file));
    const PlaneFigures f = decode_plane(set, half_finest_period(set), true, true);
    EXPECT_GT(f.valid_fraction(), 0.8);
    EXPECT_EQ(f.jumps, 0u);
  }
}

}  // namespace
}  // namespace sls
