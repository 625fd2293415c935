// Pattern sets: the Gray code's properties, the phase-shift levels against their formula,
// the blurred irradiance against an independent quadrature of the convolution, JSON round
// trips and rasterisation.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/decode/pattern_set.h"
#include "sdk/decode/pattern_shared.h"

namespace sls {
namespace {

constexpr double kPi = 3.14159265358979323846;

GrayPhaseOptions full_resolution_options() {
  GrayPhaseOptions options;
  options.gray_lowest_bit = 0;
  options.rows = true;
  return options;
}

// The Gray code word of pixel k read back from a set's (non-inverted) Gray patterns.
std::uint32_t code_from_patterns(const PatternSet& set, PatternAxis axis, int k) {
  std::uint32_t code = 0;
  for (const PatternDesc& d : set.patterns) {
    if (d.kind != PatternKind::kGrayCode || d.axis != axis || d.inverted) continue;
    if (pattern_pixel_value(d, k) == 255) code |= 1u << d.bit;
  }
  return code;
}

TEST(GrayCode, EncodeDecodeRoundTrip) {
  for (std::uint32_t v = 0; v < 5000; ++v) {
    EXPECT_EQ(gray_decode(gray_encode(v)), v);
    EXPECT_EQ(__builtin_popcount(gray_encode(v) ^ gray_encode(v + 1)), 1);
  }
  EXPECT_EQ(gray_decode(gray_encode(0xfffffffeu)), 0xfffffffeu);
}

TEST(GrayCode, AdjacentPixelsDifferInOneBitAndAllCodesAreDistinct) {
  const PatternSet set = make_gray_phase_pattern_set(full_resolution_options());
  for (PatternAxis axis : {PatternAxis::kColumns, PatternAxis::kRows}) {
    const int extent = axis == PatternAxis::kColumns ? set.projector_width : set.projector_height;
    std::set<std::uint32_t> codes;
    for (int k = 0; k < extent; ++k) {
      const std::uint32_t code = code_from_patterns(set, axis, k);
      EXPECT_EQ(gray_decode(code), static_cast<std::uint32_t>(k)) << "pixel " << k;
      codes.insert(code);
      if (k > 0) {
        EXPECT_EQ(__builtin_popcount(code ^ code_from_patterns(set, axis, k - 1)), 1) << "pixel " << k;
      }
    }
    EXPECT_EQ(codes.size(), static_cast<std::size_t>(extent));
  }
}

TEST(GrayCode, ComplementaryPatternsSumTo255) {
  const PatternSet set = make_gray_phase_pattern_set(full_resolution_options());
  int pairs = 0;
  for (std::size_t i = 0; i + 1 < set.patterns.size(); ++i) {
    const PatternDesc& a = set.patterns[i];
    const PatternDesc& b = set.patterns[i + 1];
    if (a.kind != PatternKind::kGrayCode || a.inverted) continue;
    ASSERT_EQ(b.kind, PatternKind::kGrayCode);
    ASSERT_TRUE(b.inverted);
    ASSERT_EQ(a.bit, b.bit);
    ++pairs;
    for (int k = 0; k < a.extent; ++k) {
      const int va = pattern_pixel_value(a, k);
      EXPECT_TRUE(va == 0 || va == 255);
      EXPECT_EQ(va + pattern_pixel_value(b, k), 255) << pattern_label(a) << " pixel " << k;
    }
  }
  EXPECT_EQ(pairs, 10 + 11);  // ceil(log2 912) + ceil(log2 1140)
}

TEST(GrayCode, StripeWidthOfBitB) {
  PatternDesc d;
  d.kind = PatternKind::kGrayCode;
  d.extent = 1024;
  for (int bit = 0; bit < 10; ++bit) {
    d.bit = bit;
    // Bit b flips at the odd multiples of 2^b: stripes 2^(b+1) wide.
    for (int k = 1; k < d.extent; ++k) {
      const bool flips = pattern_pixel_value(d, k) != pattern_pixel_value(d, k - 1);
      const bool odd_multiple = (k % (1 << bit)) == 0 && ((k >> bit) & 1) == 1;
      EXPECT_EQ(flips, odd_multiple) << "bit " << bit << " pixel " << k;
    }
  }
}

TEST(GrayCode, DefaultSetNumbersHalfPeriods) {
  const PatternSet set = make_gray_phase_pattern_set();
  // Bits 9..4 of g(k) are the Gray code of k >> 4: units of P/2 = 16 columns.
  for (int k = 0; k < set.projector_width; ++k) {
    EXPECT_EQ(gray_decode(code_from_patterns(set, PatternAxis::kColumns, k)) >> 4, static_cast<std::uint32_t>(k >> 4))
        << k;
  }
}

TEST(PatternSet, DefaultComposition) {
  const PatternSet set = make_gray_phase_pattern_set();
  EXPECT_EQ(set.name, "gray_phase_c9-4p32n8");
  EXPECT_EQ(set.kind, PatternSetKind::kGrayPhase);
  EXPECT_EQ(set.projector_width, 912);
  EXPECT_EQ(set.projector_height, 1140);
  ASSERT_EQ(set.size(), 22u);
  EXPECT_EQ(set.patterns[0].kind, PatternKind::kWhite);
  EXPECT_EQ(set.patterns[1].kind, PatternKind::kBlack);
  std::vector<std::string> labels;
  for (const PatternDesc& d : set.patterns) labels.push_back(pattern_label(d));
  const std::vector<std::string> expected = {
      "white",       "black",       "gray_c9",     "gray_c9_inv", "gray_c8",     "gray_c8_inv",
      "gray_c7",     "gray_c7_inv", "gray_c6",     "gray_c6_inv", "gray_c5",     "gray_c5_inv",
      "gray_c4",     "gray_c4_inv", "phase_c_p32_s0of8", "phase_c_p32_s1of8", "phase_c_p32_s2of8",
      "phase_c_p32_s3of8", "phase_c_p32_s4of8", "phase_c_p32_s5of8", "phase_c_p32_s6of8", "phase_c_p32_s7of8"};
  EXPECT_EQ(labels, expected);
  for (const PatternDesc& d : set.patterns) EXPECT_EQ(d.extent, 912);
}

TEST(PatternSet, AutomaticLowestBitAndBitCounts) {
  EXPECT_EQ(gray_code_bits(1), 0);
  EXPECT_EQ(gray_code_bits(2), 1);
  EXPECT_EQ(gray_code_bits(912), 10);
  EXPECT_EQ(gray_code_bits(1024), 10);
  EXPECT_EQ(gray_code_bits(1025), 11);
  EXPECT_EQ(gray_code_bits(1140), 11);
  EXPECT_EQ(automatic_gray_lowest_bit(32), 4);
  EXPECT_EQ(automatic_gray_lowest_bit(48), 4);  // floor(log2 48) = 5
  EXPECT_EQ(automatic_gray_lowest_bit(64), 5);
  EXPECT_EQ(automatic_gray_lowest_bit(3), 0);
}

TEST(PatternSet, RowsUseTheirOwnPeriodAndExtent) {
  GrayPhaseOptions options;
  options.rows = true;
  options.row_phase_period_px = 64;
  const PatternSet set = make_gray_phase_pattern_set(options);
  int rows = 0;
  for (const PatternDesc& d : set.patterns) {
    if (d.axis != PatternAxis::kRows || d.kind == PatternKind::kWhite || d.kind == PatternKind::kBlack) continue;
    ++rows;
    EXPECT_EQ(d.extent, 1140);
    if (d.kind == PatternKind::kPhaseShift) {
      EXPECT_EQ(d.period_px, 64);
    }
    if (d.kind == PatternKind::kGrayCode) {
      EXPECT_GE(d.bit, 5);
    }
  }
  EXPECT_EQ(rows, 2 * 6 + 8);  // bits 10..5
  EXPECT_EQ(set.size(), 22u + 20u);
}

TEST(PatternSet, RejectsUnusableOptions) {
  GrayPhaseOptions options;
  options.phase_steps = 2;
  EXPECT_THROW(make_gray_phase_pattern_set(options), Error);
  options = {};
  options.phase_period_px = 2;
  EXPECT_THROW(make_gray_phase_pattern_set(options), Error);
  options = {};
  options.columns = false;
  EXPECT_THROW(make_gray_phase_pattern_set(options), Error);
  options = {};
  options.projector_width = 0;
  try {
    make_gray_phase_pattern_set(options);
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kInvalidArgument);
  }
  PatternSet set = make_gray_phase_pattern_set();
  set.patterns[3].extent = 100;
  EXPECT_THROW(validate_pattern_set(set), Error);
  set = make_gray_phase_pattern_set();
  set.patterns[2].bit = 10;  // 912 columns need bits 0..9
  EXPECT_THROW(validate_pattern_set(set), Error);
}

// --- Phase shift levels --------------------------------------------------------------

TEST(PhaseShift, LevelsFollowTheFormula) {
  for (int period : {3, 8, 16, 31, 32, 64, 100}) {
    for (int steps : {3, 4, 6, 8, 12}) {
      for (int step = 0; step < steps; ++step) {
        PatternDesc d;
        d.kind = PatternKind::kPhaseShift;
        d.extent = 912;
        d.step = step;
        d.steps = steps;
        d.period_px = period;
        for (int k = 0; k < d.extent; ++k) {
          const long double angle = 2.0L * static_cast<long double>(kPi) *
                                    (static_cast<long double>(k) / period + static_cast<long double>(step) / steps);
          const long double x = 127.5L + 127.5L * std::cos(angle);
          const long double frac = x - std::floor(x);
          // Exact ties (cos = 0) round half up; everything else rounds to nearest and lies
          // well away from a tie, so host and device agree.
          long double expected_level;
          if (std::fabs(frac - 0.5L) < 1e-9L) {
            expected_level = std::floor(x) + 1;
            EXPECT_EQ((4 * ((static_cast<long long>(k) * steps + static_cast<long long>(step) * period) %
                            (static_cast<long long>(period) * steps))) %
                          (static_cast<long long>(period) * steps),
                      0)
                << "a near-tie that is not a quarter turn: P " << period << " N " << steps << " k " << k;
          } else {
            expected_level = std::floor(x + 0.5L);
          }
          ASSERT_EQ(pattern_pixel_value(d, k), static_cast<int>(expected_level))
              << "P " << period << " N " << steps << " j " << step << " k " << k;
        }
      }
    }
  }
}

TEST(PhaseShift, DecodesToTheLinearPhase) {
  // Sanity of the documented sign convention: the N-step estimator on the levels returns
  // 2*pi*k/P to within the 8-bit quantisation.
  const int steps = 8;
  const int period = 32;
  for (int k = 0; k < 912; ++k) {
    double s = 0;
    double c = 0;
    for (int j = 0; j < steps; ++j) {
      PatternDesc d;
      d.kind = PatternKind::kPhaseShift;
      d.extent = 912;
      d.step = j;
      d.steps = steps;
      d.period_px = period;
      const double level = pattern_pixel_value(d, k);
      s += level * std::sin(2 * kPi * j / steps);
      c += level * std::cos(2 * kPi * j / steps);
    }
    const double phase = std::atan2(-s, c);
    double expected = std::fmod(2 * kPi * k / period, 2 * kPi);
    double error = std::remainder(phase - expected, 2 * kPi);
    EXPECT_LT(std::fabs(error), 4e-3) << k;  // <= 0.02 px at P = 32
  }
}

TEST(PatternValue, OutsideTheDmdIsDark) {
  PatternDesc white;
  white.kind = PatternKind::kWhite;
  white.extent = 912;
  EXPECT_EQ(pattern_pixel_value(white, -1), 0);
  EXPECT_EQ(pattern_pixel_value(white, 912), 0);
  EXPECT_EQ(pattern_pixel_value(white, 0), 255);
  EXPECT_EQ(pattern_pixel_value(white, 911), 255);
  EXPECT_EQ(pattern_value_sharp(white, -0.5), 1.0);   // pixel 0 covers [-0.5, 0.5)
  EXPECT_EQ(pattern_value_sharp(white, -0.500001), 0.0);
  EXPECT_EQ(pattern_value_sharp(white, 911.499), 1.0);
  EXPECT_EQ(pattern_value_sharp(white, 911.5), 0.0);
  EXPECT_EQ(pattern_value_blurred(white, 1e300, 2.0), 0.0);
  EXPECT_EQ(pattern_value_blurred(white, -1e300, 2.0), 0.0);
  EXPECT_EQ(pattern_value_blurred(white, std::nan(""), 2.0), 0.0);
  // Half a Gaussian falls off the DMD at its edge.
  EXPECT_NEAR(pattern_value_blurred(white, -0.5, 1.7), 0.5, 1e-15);
  EXPECT_NEAR(pattern_value_blurred(white, 911.5, 0.4), 0.5, 1e-15);
  EXPECT_NEAR(pattern_value_blurred(white, 400.25, 3.0), 1.0, 1e-15);
  PatternDesc black = white;
  black.kind = PatternKind::kBlack;
  EXPECT_EQ(pattern_value_blurred(black, 400.25, 3.0), 0.0);
}

// --- Blurred values against an independent quadrature ------------------------------------

// Integral of L(x)/255 * N(x; u, sigma) over x, with L piecewise constant on [k-0.5, k+0.5):
// 20-point Gauss-Legendre on sub-intervals no longer than sigma/4 that never straddle an
// edge (the integrand is smooth on each), over u +- 14 sigma.
double quadrature(const PatternDesc& d, double u, double sigma) {
  static const double nodes[10] = {0.0765265211334973, 0.2277858511416451, 0.3737060887154195, 0.5108670019508271,
                                   0.6360536807265150, 0.7463319064601508, 0.8391169718222188, 0.9122344282513259,
                                   0.9639719272779138, 0.9931285991850949};
  static const double weights[10] = {0.1527533871307258, 0.1491729864726037, 0.1420961093183820,
                                     0.1316886384491766, 0.1181945319615184, 0.1019301198172404,
                                     0.0832767415767048, 0.0626720483341091, 0.0406014298003869,
                                     0.0176140071391521};
  const double a = u - 14 * sigma;
  const double b = u + 14 * sigma;
  double total = 0;
  double x0 = a;
  while (x0 < b) {
    const double next_edge = std::floor(x0 + 0.5) + 0.5;  // first edge k+0.5 above x0
    double x1 = std::fmin(std::fmin(next_edge, b), x0 + sigma / 4);
    if (x1 <= x0) x1 = std::fmin(b, x0 + sigma / 4);
    const int k = static_cast<int>(std::floor(0.5 * (x0 + x1) + 0.5));
    const double level = pattern_pixel_value(d, k) / 255.0;
    if (level != 0) {
      const double half = 0.5 * (x1 - x0);
      const double mid = 0.5 * (x0 + x1);
      double sum = 0;
      for (int i = 0; i < 10; ++i) {
        for (double sign : {-1.0, 1.0}) {
          const double x = mid + sign * half * nodes[i];
          const double t = (x - u) / sigma;
          sum += weights[i] * std::exp(-0.5 * t * t);
        }
      }
      total += level * sum * half / (sigma * std::sqrt(2 * kPi));
    }
    x0 = x1;
  }
  return total;
}

std::vector<PatternDesc> assorted_patterns() {
  const PatternSet set = make_gray_phase_pattern_set(full_resolution_options());
  std::vector<PatternDesc> out;
  for (const PatternDesc& d : set.patterns) {
    if (d.axis == PatternAxis::kColumns &&
        (d.kind != PatternKind::kGrayCode || d.bit <= 2 || d.bit == 9 || d.inverted)) {
      out.push_back(d);
    }
  }
  return out;
}

TEST(PatternValue, QuadratureIsExactOnAFlatField) {
  // Guards the quadrature's nodes and weights: a Gaussian integrates to 1.
  PatternDesc white;
  white.kind = PatternKind::kWhite;
  white.extent = 912;
  for (double sigma : {0.3, 1.0, 3.0}) EXPECT_NEAR(quadrature(white, 400.3, sigma), 1.0, 1e-13);
}

TEST(PatternValue, BlurredEqualsTheQuadratureOfTheConvolution) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> anywhere(-20.0, 932.0);
  double worst = 0;
  for (const PatternDesc& d : assorted_patterns()) {
    for (double sigma : {0.3, 1.0, 3.0}) {
      std::vector<double> points = {-3.0, -0.5, 0.0, 0.5, 255.5, 256.0, 455.75, 911.5, 913.0};
      for (int i = 0; i < 6; ++i) points.push_back(anywhere(random));
      for (double u : points) {
        const double value = pattern_value_blurred(d, u, sigma);
        const double reference = quadrature(d, u, sigma);
        worst = std::fmax(worst, std::fabs(value - reference));
        ASSERT_NEAR(value, reference, 1e-9) << pattern_label(d) << " u " << u << " sigma " << sigma;
        ASSERT_GE(value, 0.0);
        ASSERT_LE(value, 1.0 + 1e-15);
      }
    }
  }
  std::printf("largest |blurred - quadrature| = %.3g\n", worst);
}

TEST(PatternValue, BlurredTendsToSharpAsSigmaVanishes) {
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> anywhere(-5.0, 917.0);
  for (const PatternDesc& d : assorted_patterns()) {
    for (int i = 0; i < 50; ++i) {
      const double u = anywhere(random);
      const double distance_to_edge = std::fabs(u - (std::floor(u + 0.5) - 0.5));
      const double to_edge = std::fmin(distance_to_edge, 1.0 - distance_to_edge);
      const double sharp = pattern_value_sharp(d, u);
      EXPECT_EQ(pattern_value_blurred(d, u, 0.0), sharp);
      EXPECT_EQ(pattern_value_blurred(d, u, -1.0), sharp);
      if (to_edge > 1e-3) {
        // 8.5 sigma below the distance to the nearest edge: no edge within reach.
        EXPECT_EQ(pattern_value_blurred(d, u, 1e-4), sharp) << pattern_label(d) << " u " << u;
        // Within reach, the next edge's Phi(-to_edge/sigma) is far below 1e-12.
        EXPECT_NEAR(pattern_value_blurred(d, u, to_edge / 8.0), sharp, 1e-12);
      }
    }
  }
}

TEST(PatternValue, BlurIsSymmetricAtAnEdge) {
  // At a Gray edge between levels 0 and 255 the blurred value is 0.5 for any sigma much
  // smaller than the stripe.
  PatternDesc d;
  d.kind = PatternKind::kGrayCode;
  d.extent = 912;
  d.bit = 6;  // flips at odd multiples of 64
  const double edge = 64 - 0.5;
  for (double sigma : {0.01, 0.5, 2.0, 5.0}) EXPECT_NEAR(pattern_value_blurred(d, edge, sigma), 0.5, 1e-15);
}

TEST(PatternValue, FloatTableAndDoubleAgree) {
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> anywhere(-10.0, 922.0);
  for (const PatternDesc& d : assorted_patterns()) {
    const std::vector<std::uint8_t> levels = pattern_levels(d);
    const PatternLevelTable table{levels.data(), static_cast<int>(levels.size())};
    for (int i = 0; i < 40; ++i) {
      const double u = anywhere(random);
      for (double sigma : {0.0, 0.3, 1.0, 3.2, 6.4}) {
        const double value = pattern_value_blurred(d, u, sigma);
        EXPECT_EQ(pattern_value_blurred(table, u, sigma), value);
        const float single = pattern_value_blurred(d, static_cast<float>(u), static_cast<float>(sigma));
        // Compared at the float-rounded inputs (rounding u moves it by up to 3e-5 px at 900 px,
        // on slopes up to 1/(sqrt(2 pi) sigma)), float arithmetic costs a few 1e-7.
        const double same_inputs = pattern_value_blurred(d, static_cast<double>(static_cast<float>(u)),
                                                         static_cast<double>(static_cast<float>(sigma)));
        EXPECT_NEAR(static_cast<double>(single), same_inputs, 2e-6)
            << pattern_label(d) << " u " << u << " sigma " << sigma;
        EXPECT_EQ(pattern_value_blurred(table, static_cast<float>(u), static_cast<float>(sigma)), single);
      }
    }
  }
}

TEST(PatternValue, PhaseFringeContrastFollowsTheGaussianMtf) {
  // The blurred 8-step fringe keeps its sinusoid with modulation exp(-2 pi^2 sigma^2 / P^2)
  // times the DMD pixel's sinc (box of one pixel) — a physics check of the whole chain.
  const int period = 32;
  const double sigma = 3.0;
  double s = 0;
  double c = 0;
  double mean = 0;
  const int steps = 8;
  const double u = 400.3;
  for (int j = 0; j < steps; ++j) {
    PatternDesc d;
    d.kind = PatternKind::kPhaseShift;
    d.extent = 912;
    d.step = j;
    d.steps = steps;
    d.period_px = period;
    const double value = pattern_value_blurred(d, u, sigma);
    mean += value / steps;
    s += value * std::sin(2 * kPi * j / steps);
    c += value * std::cos(2 * kPi * j / steps);
  }
  const double modulation = 2 * std::hypot(s, c) / steps / mean;
  const double box = std::sin(kPi / period) / (kPi / period);
  const double expected = std::exp(-2 * kPi * kPi * sigma * sigma / (period * period)) * box;
  EXPECT_NEAR(modulation, expected, 5e-3);  // 8-bit quantisation of the levels
  double phase = std::atan2(-s, c);
  EXPECT_NEAR(std::remainder(phase - 2 * kPi * u / period, 2 * kPi), 0.0, 5e-3);
}

// --- JSON and rasterisation --------------------------------------------------------------

TEST(PatternSetJson, RoundTrip) {
  for (const GrayPhaseOptions& options : {GrayPhaseOptions{}, full_resolution_options()}) {
    const PatternSet set = make_gray_phase_pattern_set(options);
    const std::string json = pattern_set_to_json(set);
    EXPECT_EQ(json.find('\n'), std::string::npos);
    const PatternSet back = pattern_set_from_json(json);
    EXPECT_EQ(back, set);
    EXPECT_EQ(pattern_set_to_json(back), json);
  }
  const std::string json = pattern_set_to_json(make_gray_phase_pattern_set());
  EXPECT_NE(json.find("\"format\":\"slscan-pattern-set\""), std::string::npos) << json;
  EXPECT_NE(json.find("{\"kind\":\"gray_code\",\"axis\":\"columns\",\"bit\":9,\"inverted\":false}"), std::string::npos)
      << json;
  EXPECT_NE(json.find("{\"kind\":\"phase_shift\",\"axis\":\"columns\",\"step\":0,\"steps\":8,\"period_px\":32}"),
            std::string::npos)
      << json;
}

ErrorCode parse_error(const std::string& json) {
  try {
    pattern_set_from_json(json);
  } catch (const Error& error) {
    return error.code();
  }
  return ErrorCode::kInternal;
}

TEST(PatternSetJson, RejectsBrokenInput) {
  const std::string good = pattern_set_to_json(make_gray_phase_pattern_set());
  auto replaced = [&good](const std::string& from, const std::string& to) {
    std::string s = good;
    const std::size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  EXPECT_EQ(parse_error(""), ErrorCode::kFormat);
  EXPECT_EQ(parse_error("[1, 2]"), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(good.substr(0, good.size() / 2)), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(replaced("slscan-pattern-set", "other")), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(replaced("\"format_version\":1", "\"format_version\":3")), ErrorCode::kVersionMismatch);
  EXPECT_EQ(parse_error(replaced("\"kind\":\"gray_code\"", "\"kind\":\"sawtooth\"")), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(replaced("\"axis\":\"columns\"", "\"axis\":\"diagonal\"")), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(replaced("\"bit\":9", "\"bit\":\"9\"")), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(replaced("\"bit\":9", "\"bit\":12")), ErrorCode::kInvalidArgument);
  EXPECT_EQ(parse_error(replaced("\"image_count\":22", "\"image_count\":21")), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(replaced("\"width\":912", "\"width\":-912")), ErrorCode::kFormat);
  EXPECT_EQ(parse_error(replaced("\"step\":0,\"steps\":8", "\"step\":8,\"steps\":8")), ErrorCode::kInvalidArgument);
  // Unknown extra members are ignored (forward compatibility).
  EXPECT_NO_THROW(pattern_set_from_json(replaced("\"name\":", "\"comment\":\"x\",\"name\":")));
}

TEST(Rasterize, MatchesPixelValues) {
  GrayPhaseOptions options = full_resolution_options();
  options.projector_width = 40;  // small DMD: every pixel checked quickly
  options.projector_height = 24;
  options.phase_period_px = 7;
  const PatternSet set = make_gray_phase_pattern_set(options);
  for (std::size_t i = 0; i < set.size(); ++i) {
    const PatternDesc& d = set.patterns[i];
    const Image8u image = rasterize_pattern(set, i);
    ASSERT_EQ(image.width(), 40);
    ASSERT_EQ(image.height(), 24);
    const std::vector<std::uint8_t> levels = pattern_levels(d);
    for (int y = 0; y < 24; ++y) {
      for (int x = 0; x < 40; ++x) {
        const int k = d.axis == PatternAxis::kRows ? y : x;
        ASSERT_EQ(image(x, y), pattern_pixel_value(d, k)) << pattern_label(d) << " " << x << "," << y;
        ASSERT_EQ(image(x, y), levels[static_cast<std::size_t>(k)]);
      }
    }
  }
  EXPECT_THROW(rasterize_pattern(set, set.size()), Error);
  EXPECT_THROW(rasterize_pattern(set.patterns[2], 41, 24), Error);
  // The default DMD image is the DLPC350's native 912 x 1140.
  const Image8u full = rasterize_pattern(make_gray_phase_pattern_set(), 14);
  EXPECT_EQ(full.width(), 912);
  EXPECT_EQ(full.height(), 1140);
}

}  // namespace
}  // namespace sls
