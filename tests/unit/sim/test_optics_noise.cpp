// The simulated rig's noise and optics: Philox against the published known answers, the
// samplers' moments and distributions within statistical bounds, the sensor's photon
// transfer curve and clamps, thin-lens defocus against hand-computed values, and the
// default rig against the numbers in docs/simulator-optics.md.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/noise_shared.h"
#include "drivers/sim/optics_shared.h"
#include "sdk/decode/pattern_shared.h"

namespace sls::sim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// --- Philox ------------------------------------------------------------------------------

// Random123's kat_vectors, philox4x32 with 10 rounds.
TEST(Philox, KnownAnswerVectors) {
  struct Kat {
    Philox4x32Counter counter;
    Philox4x32Key key;
    Philox4x32Counter expected;
  };
  const Kat kats[] = {
      {{{0, 0, 0, 0}}, {{0, 0}}, {{0x6627e8d5u, 0xe169c58du, 0xbc57ac4cu, 0x9b00dbd8u}}},
      {{{0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu}},
       {{0xffffffffu, 0xffffffffu}},
       {{0x408f276du, 0x41c83b0eu, 0xa20bc7c6u, 0x6d5451fdu}}},
      {{{0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u}},
       {{0xa4093822u, 0x299f31d0u}},
       {{0xd16cfe09u, 0x94fdccebu, 0x5001e420u, 0x24126ea1u}}},
  };
  for (const Kat& kat : kats) {
    const Philox4x32Counter out = philox4x32_10(kat.counter, kat.key);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(out.v[i], kat.expected.v[i]) << std::hex << "word " << i;
  }
}

TEST(NoiseStream, LayoutOfCounterAndKey) {
  NoiseKey key;
  key.seed = 0x0123456789abcdefull;
  key.frame = 7;
  key.image = 3;
  key.pixel = 4000 * 2999 + 3999;
  NoiseStream stream = make_noise_stream(key, kReadNoiseStream);
  const Philox4x32Counter first = philox4x32_10({{key.pixel, 3, 7, 0x01000000u}}, {{0x89abcdefu, 0x01234567u}});
  const Philox4x32Counter second = philox4x32_10({{key.pixel, 3, 7, 0x01000001u}}, {{0x89abcdefu, 0x01234567u}});
  for (int i = 0; i < 4; ++i) EXPECT_EQ(stream.next_u32(), first.v[i]);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(stream.next_u32(), second.v[i]);
}

TEST(NoiseStream, UniformsAreOpenAndFlat) {
  NoiseKey key;
  key.seed = 42;
  const int n = 1000000;
  double sum = 0;
  double sum2 = 0;
  double sum_float = 0;
  std::vector<int> bins(20, 0);
  for (int i = 0; i < n; ++i) {
    key.pixel = static_cast<std::uint32_t>(i);
    NoiseStream s = make_noise_stream(key, kUserStream);
    const double u = s.uniform();
    const float f = s.uniform_float();
    ASSERT_GT(u, 0.0);
    ASSERT_LT(u, 1.0);
    ASSERT_GT(f, 0.0f);
    ASSERT_LT(f, 1.0f);
    sum += u;
    sum2 += u * u;
    sum_float += static_cast<double>(f);
    ++bins[static_cast<std::size_t>(u * 20)];
  }
  const double mean = sum / n;
  const double variance = sum2 / n - mean * mean;
  EXPECT_NEAR(mean, 0.5, 5 * std::sqrt(1.0 / 12 / n));
  EXPECT_NEAR(sum_float / n, 0.5, 5 * std::sqrt(1.0 / 12 / n));
  EXPECT_NEAR(variance, 1.0 / 12, 5 * std::sqrt(1.0 / 180 / n));  // Var of u^2-based estimate
  double chi2 = 0;
  for (int count : bins) chi2 += (count - n / 20.0) * (count - n / 20.0) / (n / 20.0);
  EXPECT_LT(chi2, 19 + 5 * std::sqrt(2 * 19.0)) << "uniform histogram chi-square";
  // The extreme values of the 52-bit grid stay strictly inside (0, 1).
  NoiseStream edge = make_noise_stream(key, 0);
  edge.used = 0;
  edge.words[0] = edge.words[1] = 0;
  EXPECT_EQ(edge.uniform(), 0.5 * std::ldexp(1.0, -52));
  edge.used = 0;
  edge.words[0] = edge.words[1] = 0xffffffffu;
  EXPECT_LT(edge.uniform(), 1.0);
  edge.used = 0;
  edge.words[0] = 0xffffffffu;
  EXPECT_LT(edge.uniform_float(), 1.0f);
}

TEST(NoiseStream, StreamsAndKeysAreIndependent) {
  NoiseKey key;
  key.seed = 1;
  std::set<std::uint32_t> firsts;
  for (std::uint32_t stream = 0; stream < 4; ++stream) {
    for (std::uint32_t frame = 0; frame < 4; ++frame) {
      for (std::uint32_t image = 0; image < 4; ++image) {
        for (std::uint32_t pixel = 0; pixel < 4; ++pixel) {
          for (std::uint64_t seed : {1ull, 2ull, 1ull << 32}) {
            NoiseKey k = key;
            k.seed = seed;
            k.frame = frame;
            k.image = image;
            k.pixel = pixel;
            NoiseStream s = make_noise_stream(k, stream);
            firsts.insert(s.next_u32());
          }
        }
      }
    }
  }
  EXPECT_EQ(firsts.size(), 4u * 4 * 4 * 4 * 3);
  // Neighbouring pixels' normals are uncorrelated.
  const int n = 200000;
  double sxy = 0;
  double previous = 0;
  for (int i = 0; i <= n; ++i) {
    key.pixel = static_cast<std::uint32_t>(i);
    NoiseStream s = make_noise_stream(key, kReadNoiseStream);
    const double z = s.normal();
    if (i > 0) sxy += z * previous;
    previous = z;
  }
  EXPECT_NEAR(sxy / n, 0.0, 5 / std::sqrt(n));
}

// --- Gaussian ----------------------------------------------------------------------------

TEST(Samplers, GaussianMoments) {
  const int n = 1000000;
  NoiseKey key;
  key.seed = 2024;
  NoiseStream s = make_noise_stream(key, kUserStream);
  std::vector<double> z(n);
  double mean = 0;
  for (double& v : z) {
    v = s.normal();
    mean += v;
  }
  mean /= n;
  double m2 = 0, m3 = 0, m4 = 0;
  for (double v : z) {
    const double d = v - mean;
    m2 += d * d;
    m3 += d * d * d;
    m4 += d * d * d * d;
  }
  m2 /= n;
  m3 /= n;
  m4 /= n;
  const double skewness = m3 / std::pow(m2, 1.5);
  const double kurtosis = m4 / (m2 * m2);
  std::printf("normal: mean %.5f variance %.5f skewness %.5f kurtosis %.5f\n", mean, m2, skewness, kurtosis);
  // 5 sigma of each estimator under normality.
  EXPECT_NEAR(mean, 0.0, 5 * std::sqrt(1.0 / n));
  EXPECT_NEAR(m2, 1.0, 5 * std::sqrt(2.0 / n));
  EXPECT_NEAR(skewness, 0.0, 5 * std::sqrt(6.0 / n));
  EXPECT_NEAR(kurtosis, 3.0, 5 * std::sqrt(24.0 / n));
  // Tails: P(|z| > 3) = 0.0027.
  const auto beyond = std::count_if(z.begin(), z.end(), [](double v) { return std::fabs(v) > 3; });
  const double p3 = 0.0026997960632601866;
  EXPECT_NEAR(static_cast<double>(beyond) / n, p3, 5 * std::sqrt(p3 * (1 - p3) / n));
}

// --- Poisson -----------------------------------------------------------------------------

struct SampleMoments {
  double mean = 0;
  double variance = 0;
  double mean_bound = 0;      // 5 standard errors
  double variance_bound = 0;  // 5 standard errors, from the sample's fourth moment
};

SampleMoments moments(const std::vector<double>& x) {
  const double n = static_cast<double>(x.size());
  SampleMoments m;
  for (double v : x) m.mean += v;
  m.mean /= n;
  double m2 = 0, m4 = 0;
  for (double v : x) {
    const double d = v - m.mean;
    m2 += d * d;
    m4 += d * d * d * d;
  }
  m2 /= n;
  m4 /= n;
  m.variance = m2 * n / (n - 1);
  m.mean_bound = 5 * std::sqrt(m2 / n);
  m.variance_bound = 5 * std::sqrt((m4 - m2 * m2) / n);
  return m;
}

double poisson_log_pmf(double mean, int k) { return -mean + k * std::log(mean) - std::lgamma(k + 1.0); }

// Pearson chi-square against the Poisson pmf, bins with expected counts >= 20 (tails merged).
// Returns chi2 - (df + 5 sqrt(2 df)): negative passes (a 5 sigma bound).
double chi_square_excess(const std::vector<double>& samples, double mean) {
  std::map<int, double> observed;
  for (double v : samples) observed[static_cast<int>(v)] += 1;
  const double n = static_cast<double>(samples.size());
  const int top = static_cast<int>(mean + 12 * std::sqrt(mean) + 20);
  double chi2 = 0;
  int bins = 0;
  double pending_expected = 0;
  double pending_observed = 0;
  for (int k = 0; k <= top; ++k) {
    pending_expected += n * std::exp(poisson_log_pmf(mean, k));
    pending_observed += observed.count(k) ? observed[k] : 0;
    if (pending_expected >= 20) {
      // Anything left above `top` is folded into the last bin below.
      chi2 += (pending_observed - pending_expected) * (pending_observed - pending_expected) / pending_expected;
      ++bins;
      pending_expected = pending_observed = 0;
    }
  }
  double above = 0;
  for (const auto& [k, count] : observed) {
    if (k > top) above += count;
  }
  pending_observed += above;
  pending_expected = std::max(pending_expected, 1e-300);
  if (pending_observed > 0 || pending_expected > 1e-3) {
    chi2 += (pending_observed - pending_expected) * (pending_observed - pending_expected) / pending_expected;
    ++bins;
  }
  const double df = bins - 1;
  std::printf("poisson %.1f: chi2 %.1f over %d bins\n", mean, chi2, bins);
  return chi2 - (df + 5 * std::sqrt(2 * df));
}

TEST(Samplers, PoissonMomentsAndDistribution) {
  const int n = 1000000;
  for (double mean : {0.5, 5.0, 9.99, 10.0, 50.0, 500.0, 999.0, 1000.0, 5000.0}) {
    NoiseKey key;
    key.seed = 77;
    std::vector<double> x(n);
    for (int i = 0; i < n; ++i) {
      key.pixel = static_cast<std::uint32_t>(i);
      NoiseStream s = make_noise_stream(key, kShotNoiseStream);
      x[static_cast<std::size_t>(i)] = poisson_sample(s, mean);
    }
    const SampleMoments m = moments(x);
    std::printf("poisson %.2f: mean %.4f (+-%.4f) variance %.3f (+-%.3f)\n", mean, m.mean, m.mean_bound, m.variance,
                m.variance_bound);
    EXPECT_NEAR(m.mean, mean, m.mean_bound) << mean;
    EXPECT_NEAR(m.variance, mean, m.variance_bound) << mean;
    if (mean < kPoissonGaussianFrom) {
      for (double v : x) ASSERT_EQ(v, std::floor(v));  // exact branches give integers
      EXPECT_LT(chi_square_excess(x, mean), 0.0) << mean;
    }
  }
}

TEST(Samplers, PoissonEdgeCases) {
  NoiseKey key;
  NoiseStream s = make_noise_stream(key, 0);
  EXPECT_EQ(poisson_sample(s, 0.0), 0.0);
  EXPECT_EQ(poisson_sample(s, -3.0), 0.0);
  EXPECT_EQ(poisson_sample(s, std::nan("")), 0.0);
  EXPECT_GE(poisson_sample(s, 1e-12), 0.0);
  // log_factorial against lgamma (host only: the device cannot call glibc's).
  for (int k = 0; k < 3000; k += (k < 40 ? 1 : 37)) {
    EXPECT_NEAR(log_factorial(k), std::lgamma(k + 1.0), 1e-12 * std::max(1.0, std::lgamma(k + 1.0))) << k;
  }
}

// --- Sensor --------------------------------------------------------------------------------

TEST(Sensor, PhotonTransferCurve) {
  const SensorModel sensor = default_camera_sensor();
  const double g = sensor.gain_e_per_dn;
  const int n = 400000;
  for (double mu : {0.0, 3.0, 20.0, 200.0, 999.0, 2000.0, 6000.0, 9000.0}) {
    NoiseKey key;
    key.seed = 5;
    key.frame = 1;
    key.image = static_cast<std::uint32_t>(mu);
    std::vector<double> dn(n);
    for (int i = 0; i < n; ++i) {
      key.pixel = static_cast<std::uint32_t>(i);
      dn[static_cast<std::size_t>(i)] = sensor_response(sensor, mu, key);
    }
    const SampleMoments m = moments(dn);
    const double expected_mean = sensor.black_level_dn + mu / g;
    const double expected_variance = mu / (g * g) + sensor.read_noise_e * sensor.read_noise_e / (g * g) + 1.0 / 12;
    std::printf("PTC mu %6.0f e-: mean %9.3f DN (expected %9.3f), variance %8.3f DN^2 (expected %8.3f +- %.3f)\n", mu,
                m.mean, expected_mean, m.variance, expected_variance, m.variance_bound);
    EXPECT_NEAR(m.mean, expected_mean, m.mean_bound) << mu;
    EXPECT_NEAR(m.variance, expected_variance, m.variance_bound) << mu;
  }
}

TEST(Sensor, SaturationAndClamps) {
  SensorModel sensor = default_camera_sensor();
  NoiseKey key;
  key.seed = 9;
  // The pixel saturates at the full well: black + 10500 / 2.6 = 4070.46 DN, read noise on top.
  int low = 1 << 30, high = 0;
  for (std::uint32_t i = 0; i < 100000; ++i) {
    key.pixel = i;
    const int dn = sensor_response(sensor, 1e7, key);
    low = std::min(low, dn);
    high = std::max(high, dn);
  }
  const double saturated = sensor.black_level_dn + sensor.full_well_e / sensor.gain_e_per_dn;
  EXPECT_GE(low, static_cast<int>(std::floor(saturated - 6 * sensor.read_noise_e / sensor.gain_e_per_dn)));
  EXPECT_LE(high, static_cast<int>(std::ceil(saturated + 6 * sensor.read_noise_e / sensor.gain_e_per_dn)));
  EXPECT_LT(high, sensor_max_dn(sensor));
  EXPECT_EQ(sensor_response_noiseless(sensor, 1e7), 4070);  // round(4070.46)
  // With a higher gain the ADC clips first: every value is 4095.
  sensor.gain_e_per_dn = 1.0;
  for (std::uint32_t i = 0; i < 1000; ++i) {
    key.pixel = i;
    EXPECT_EQ(sensor_response(sensor, 9000.0, key), 4095);
  }
  // No black level: half of the dark pixels would be negative; they clamp to 0.
  sensor = default_camera_sensor();
  sensor.black_level_dn = 0;
  int zeros = 0;
  for (std::uint32_t i = 0; i < 10000; ++i) {
    key.pixel = i;
    const int dn = sensor_response(sensor, 0.0, key);
    ASSERT_GE(dn, 0);
    zeros += dn == 0;
  }
  EXPECT_GT(zeros, 5000);  // round(N(0, 0.92 DN)) <= 0 for about 70 %
  EXPECT_EQ(sensor_max_dn(sensor), 4095);
  sensor.bit_depth = 8;
  EXPECT_EQ(sensor_max_dn(sensor), 255);
  EXPECT_EQ(sensor_quantize(sensor, 1e9), 255);
  EXPECT_EQ(sensor_quantize(sensor, -5.0), 0);
  EXPECT_EQ(sensor_quantize(sensor, std::nan("")), 0);
}

TEST(Sensor, NoiselessResponseAndGamma) {
  SensorModel sensor = default_camera_sensor();
  EXPECT_EQ(sensor_response_noiseless(sensor, 0.0), 32);
  EXPECT_EQ(sensor_response_noiseless(sensor, 2600.0), 1032);
  EXPECT_EQ(sensor_response_noiseless(sensor, -5.0), 32);
  sensor.gamma = 0.5;
  const double range = 4095.0 - 32.0;
  const double electrons = 0.16 * range * sensor.gain_e_per_dn;  // 16 % of the range, linear
  EXPECT_EQ(sensor_response_noiseless(sensor, electrons), static_cast<int>(std::floor(32 + 0.4 * range + 0.5)));
}

TEST(Sensor, SameKeySameNoiseDifferentKeyDifferentNoise) {
  const SensorModel sensor = default_camera_sensor();
  NoiseKey key;
  key.seed = 31;
  key.frame = 12;
  key.image = 5;
  key.pixel = 123456;
  const int reference = sensor_response(sensor, 3000.0, key);
  for (int repeat = 0; repeat < 10; ++repeat) EXPECT_EQ(sensor_response(sensor, 3000.0, key), reference);
  // Changing any part of the key changes the draw (checked over many pixels: a single DN
  // can coincide by chance).
  int differ_frame = 0, differ_image = 0, differ_seed = 0;
  for (std::uint32_t i = 0; i < 1000; ++i) {
    NoiseKey a = key;
    a.pixel = i;
    NoiseKey b = a;
    b.frame += 1;
    NoiseKey c = a;
    c.image += 1;
    NoiseKey d = a;
    d.seed += 1;
    const int va = sensor_response(sensor, 3000.0, a);
    differ_frame += va != sensor_response(sensor, 3000.0, b);
    differ_image += va != sensor_response(sensor, 3000.0, c);
    differ_seed += va != sensor_response(sensor, 3000.0, d);
  }
  // Two draws with sigma ~21 DN coincide with probability ~1/75.
  EXPECT_GT(differ_frame, 950);
  EXPECT_GT(differ_image, 950);
  EXPECT_GT(differ_seed, 950);
}

// --- Optics --------------------------------------------------------------------------------

TEST(Optics, DefocusMatchesTheThinLensByHand) {
  const LensModel lens = default_camera_lens();
  // f = 100 mm * 1.15 / 2.15 = 53.488372 mm, A = f / 8 = 6.686047 mm, focused at 100 mm:
  // v_f = 115 mm. A point at 105 mm images at v = f s / (s - f) = 109.029345 mm, so the blur
  // disk on the sensor is c = A |v_f - v| / v = 6.686047 * 5.970655 / 109.029345 = 0.366141 mm.
  EXPECT_NEAR(lens.focal_length_m, 53.488372e-3, 1e-9);
  EXPECT_NEAR(lens_image_distance_m(lens, 0.100), 0.115, 1e-12);
  EXPECT_NEAR(lens_image_distance_m(lens, 0.105), 109.029345e-3, 1e-9);
  EXPECT_NEAR(circle_of_confusion_m(lens, 0.105), 0.366141e-3, 1e-9);
  // Independently through v and A:
  const double v = lens_image_distance_m(lens, 0.095);
  const double aperture = lens.focal_length_m / lens.f_number;
  EXPECT_NEAR(circle_of_confusion_m(lens, 0.095), aperture * std::fabs(0.115 - v) / v, 1e-15);
  // Its Gaussian: sigma = c/4 = 91.54 um, with diffraction (0.42 * 0.55 um * 8 * 2.15 =
  // 3.973 um) in quadrature: 91.62 um = 26.56 px; the pixel box adds 1/12 px^2.
  const SensorModel sensor = default_camera_sensor();
  const double sigma_m = std::hypot(0.366141e-3 / 4, 0.42 * 0.55e-6 * 8 * 2.15);
  EXPECT_NEAR(lens_blur_sigma_m(lens, 0.105), sigma_m, 1e-9);
  EXPECT_NEAR(defocus_sigma_px(lens, sensor, 0.105), std::sqrt(std::pow(sigma_m / 3.45e-6, 2) + 1.0 / 12), 1e-3);
  EXPECT_NEAR(defocus_sigma_px(lens, sensor, 0.105), 26.56, 0.01);
}

TEST(Optics, DefocusIsTheFloorAtFocusAndGrowsAboutLinearly) {
  const LensModel lens = default_camera_lens();
  const SensorModel sensor = default_camera_sensor();
  EXPECT_EQ(circle_of_confusion_m(lens, lens.focus_distance_m), 0.0);
  const double diffraction_px = 0.42 * lens.wavelength_m * working_f_number(lens) / sensor.pixel_pitch_m;
  const double floor_px = std::sqrt(diffraction_px * diffraction_px + 1.0 / 12);
  EXPECT_NEAR(working_f_number(lens), 8 * 2.15, 1e-12);
  EXPECT_NEAR(floor_px, 1.187, 1e-3);
  EXPECT_DOUBLE_EQ(defocus_sigma_px(lens, sensor, lens.focus_distance_m), floor_px);
  // The blur disk grows linearly with |depth - focus| to first order: c ~ m^2 |d| / (N (1 + m)).
  const double m = lens_magnification(lens);
  const double slope = m * m / (lens.f_number * (1 + m));
  double previous = 0;
  for (double d : {1e-5, 1e-4, 5e-4, 1e-3, 2e-3, 5e-3}) {
    for (double sign : {-1.0, 1.0}) {
      const double c = circle_of_confusion_m(lens, lens.focus_distance_m + sign * d);
      // Exactly slope * d * s_f / s: the near side blurs slightly more.
      EXPECT_NEAR(c, slope * d * lens.focus_distance_m / (lens.focus_distance_m + sign * d), 1e-15);
      EXPECT_NEAR(c / (slope * d), 1.0, 1.1 * d / lens.focus_distance_m);
    }
    const double sigma = defocus_sigma_px(lens, sensor, lens.focus_distance_m + d);
    EXPECT_GT(sigma, previous);
    previous = sigma;
  }
  EXPECT_EQ(circle_of_confusion_m(lens, 0.0), HUGE_VAL);
  EXPECT_EQ(circle_of_confusion_m(lens, -1.0), HUGE_VAL);
  // At the focal length the beam leaves parallel: the disk is the aperture.
  EXPECT_NEAR(circle_of_confusion_m(lens, lens.focal_length_m), lens.focal_length_m / lens.f_number, 1e-15);
}

TEST(Optics, DepthOfFieldInvertsTheBlurCircle) {
  const LensModel lens = default_camera_lens();
  for (double c_max : {20e-6, 100e-6, 366.141e-6}) {
    const DepthOfField dof = depth_of_field(lens, c_max);
    EXPECT_LT(dof.near_m, lens.focus_distance_m);
    EXPECT_GT(dof.far_m, lens.focus_distance_m);
    EXPECT_NEAR(circle_of_confusion_m(lens, dof.near_m), c_max, 1e-12);
    EXPECT_NEAR(circle_of_confusion_m(lens, dof.far_m), c_max, 1e-12);
  }
  EXPECT_NEAR(depth_of_field(lens, 366.141e-6).far_m, 0.105, 1e-7);
  // A blur limit as large as the aperture's image never bounds the far side.
  EXPECT_EQ(depth_of_field(lens, 1.0).far_m, HUGE_VAL);
}

TEST(Optics, ProjectorBlurInDmdPixels) {
  const ProjectorModel projector = default_projector_optics();
  const Vec2d at_focus = projector_blur_sigma_px(projector, 0.100);
  // Diffraction only: 0.42 * 0.55 um * 8 * (1 + 0.6156) = 2.986 um = 0.276 columns, 0.553 rows.
  EXPECT_NEAR(at_focus.x, 0.2765, 1e-3);
  EXPECT_NEAR(at_focus.y, 2 * at_focus.x, 1e-12);  // rows are half the column pitch
  // The usable-depth limit, 5 mm along the camera axis = 4.53 mm along the projector's.
  const Vec2d near = projector_blur_sigma_px(projector, 0.100 - 0.005 * std::cos(25 * kPi / 180));
  EXPECT_NEAR(near.x, 3.23, 0.01);
  EXPECT_NEAR(projector_relative_irradiance(projector, 0.0), 0.001, 1e-15);
  EXPECT_NEAR(projector_relative_irradiance(projector, 1.0), 1.0, 1e-15);
  EXPECT_NEAR(projector_relative_irradiance(projector, 0.5), 0.5005, 1e-15);
  ProjectorModel ideal = projector;
  ideal.contrast_ratio = 0;
  EXPECT_EQ(projector_relative_irradiance(ideal, 0.0), 0.0);
}

// A projector's gamma applies to each DMD pixel's light before the lens blurs it: sharp, the
// value is (L/255)^gamma; blurred, the convolution of those per-pixel values (checked against a
// direct numerical integral); gamma 1 is the linear projector exactly.
TEST(Optics, ProjectorGammaAppliesPerDmdPixelBeforeTheBlur) {
  PatternDesc phase;
  phase.kind = PatternKind::kPhaseShift;
  phase.extent = 912;
  phase.steps = 8;
  phase.step = 3;
  phase.period_px = 32;
  const ProjectorGammaResponse gamma{2.2};
  for (int k = 100; k < 140; ++k) {
    const double level = pattern_pixel_value(phase, k);
    EXPECT_NEAR(pattern_value_blurred(phase, static_cast<double>(k), 0.0, gamma), std::pow(level / 255.0, 2.2), 1e-15);
  }
  for (const double sigma : {0.3, 1.0, 2.5}) {
    for (double u = 100.0; u < 140.0; u += 0.37) {
      EXPECT_EQ(pattern_value_blurred(phase, u, sigma, ProjectorGammaResponse{1.0}), pattern_value_blurred(phase, u, sigma));
      // Midpoint rule over +-10 sigma, 200 samples a DMD pixel.
      double integral = 0.0;
      const double step = 1.0 / 200.0;
      for (double x = u - 10.0 * sigma; x < u + 10.0 * sigma; x += step) {
        const double at = x + 0.5 * step;
        const double level = pattern_pixel_value(phase, static_cast<int>(std::floor(at + 0.5)));
        integral += std::pow(level / 255.0, 2.2) * std::exp(-0.5 * (at - u) * (at - u) / (sigma * sigma)) * step;
      }
      integral /= sigma * std::sqrt(2.0 * kPi);
      EXPECT_NEAR(pattern_value_blurred(phase, u, sigma, gamma), integral, 2e-4) << u << " " << sigma;
    }
  }
}

// The numbers docs/simulator-optics.md states; if one changes, the document changes with it.
TEST(Optics, DefaultRigMatchesTheDocument) {
  const RigOptics rig = default_rig_optics();
  const SensorModel& cam = rig.camera_sensor;
  EXPECT_EQ(cam.width, 4000);
  EXPECT_EQ(cam.height, 3000);
  EXPECT_EQ(cam.bit_depth, 12);
  EXPECT_DOUBLE_EQ(cam.full_well_e, 10500);
  EXPECT_DOUBLE_EQ(cam.read_noise_e, 2.4);
  const double m = lens_magnification(rig.camera_lens);
  EXPECT_NEAR(m, 1.15, 1e-12);
  EXPECT_NEAR(cam.pixel_pitch_m / m, 3.0e-6, 1e-12);          // 3 um per pixel on the object
  EXPECT_NEAR(cam.width * cam.pixel_pitch_m / m, 12e-3, 1e-9);  // 12 x 9 mm field
  EXPECT_NEAR(cam.height * cam.pixel_pitch_m / m, 9e-3, 1e-9);
  EXPECT_NEAR(rig.working_distance_m, 0.100, 1e-15);
  EXPECT_NEAR(rig.camera_lens.focal_length_m, 53.488e-3, 1e-6);
  const CameraIntrinsics k = camera_intrinsics(rig.camera_lens, cam);
  EXPECT_NEAR(k.fx, 33333.333, 1e-3);
  EXPECT_DOUBLE_EQ(k.cx, 1999.5);

  const ProjectorModel& p = rig.projector;
  EXPECT_EQ(p.width, 912);
  EXPECT_EQ(p.height, 1140);
  const double mp = 1.0 / lens_magnification(p.lens);  // object / DMD
  EXPECT_NEAR(p.width * p.pixel_pitch_x_m * mp, 16e-3, 1e-9);
  EXPECT_NEAR(p.height * p.pixel_pitch_y_m * mp, 10e-3, 1e-9);
  EXPECT_NEAR(p.pixel_pitch_x_m * mp, 17.54e-6, 0.01e-6);  // one column on the object
  EXPECT_NEAR(p.lens.focal_length_m, 38.10e-3, 0.01e-3);
  const CameraIntrinsics kp = projector_intrinsics(p);
  EXPECT_NEAR(kp.fy, 2 * kp.fx, 1e-9);

  EXPECT_NEAR(rig.triangulation_angle_rad, 25 * kPi / 180, 1e-15);
  EXPECT_NEAR(rig.baseline_m, 43.29e-3, 0.01e-3);
  EXPECT_NEAR(p.white_electrons, 7350, 1e-9);
  EXPECT_NEAR(rig.ambient_electrons, 44.1, 1e-9);

  // Usable depth of field: over +-5 mm the combined camera and projector blur keeps >= 50 %
  // of the 32-column fringes' contrast (0.56 mm on the object), the criterion of the document.
  const double period_object = 32 * p.pixel_pitch_x_m * mp;
  EXPECT_NEAR(period_object, 0.561e-3, 0.001e-3);
  const double cos_angle = std::cos(rig.triangulation_angle_rad);
  for (double d : {-5e-3, -2e-3, 0.0, 2e-3, 5e-3}) {
    const double camera_object = lens_blur_sigma_m(rig.camera_lens, 0.1 + d) / m;
    const double projector_object = lens_blur_sigma_m(p.lens, 0.1 + d * cos_angle) * mp;
    const double mtf = gaussian_mtf(std::hypot(camera_object, projector_object), period_object);
    std::printf("depth %+.0f mm: camera sigma %.1f um, projector sigma %.1f um on the object, fringe MTF %.3f\n",
                d * 1e3, camera_object * 1e6, projector_object * 1e6, mtf);
    EXPECT_GE(mtf, 0.50) << d;
  }
  // ... and f/5.6 would not reach it.
  LensModel wider = rig.camera_lens;
  wider.f_number = 5.6;
  EXPECT_LT(gaussian_mtf(lens_blur_sigma_m(wider, 0.095) / m, period_object), 0.5);
}

TEST(Optics, GaussianMtf) {
  EXPECT_EQ(gaussian_mtf(0.0, 1.0), 1.0);
  EXPECT_NEAR(gaussian_mtf(0.1874, 1.0), 0.5, 1e-3);
  EXPECT_NEAR(gaussian_mtf(1.0, 4.0), std::exp(-2 * kPi * kPi / 16), 1e-15);
}

}  // namespace
}  // namespace sls::sim
