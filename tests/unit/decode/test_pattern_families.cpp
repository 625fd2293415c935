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
              "max %.3f px, %zu beyond %.1f px\n",
              set.name.c_str(), screw ? "knurled screw" : "plane", noise ? "noisy" : "noise-free", f.compared, f.valid_fraction(), f.rms_px, f.max_px, f.jumps, jump_px);
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

}  // namespace
}  // namespace sls
