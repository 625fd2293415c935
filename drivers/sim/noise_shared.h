// Sensor noise of the simulated camera, shared by the CPU and CUDA renderers (DESIGN.md
// section 6). Randomness is counter-based: every draw is a pure function of (seed, frame,
// image, pixel, stream, block), so the CPU and CUDA renders of the same scene draw the same
// random bits in any thread order, and re-rendering one pixel reproduces it.
//
// Generator: Philox4x32-10 (Salmon, Moraes, Dror, Shaw, "Parallel random numbers: as easy
// as 1, 2, 3", SC 2011), checked against the Random123 known-answer vectors in the tests.
//   counter = {pixel, image, frame, (stream << 24) | block},  key = {seed lo, seed hi}
// Streams keep the draws of different purposes apart (shot noise cannot shift read noise when
// the Poisson sampler takes a different number of uniforms); a stream has 2^24 blocks of four
// 32-bit words, far more than any sampler here consumes.
//
// The integer bits are identical on host and device. Floating-point transforms (log, cos) may
// differ by an ulp between the host libm and CUDA's, and nvcc contracts a*b+c into FMAs, so a
// digital number can differ only where the analog value sits within ~1e-12 DN of a rounding
// boundary (or a PTRS accept test as close to its threshold): on an H200, 12.6 million
// sensor_response calls gave identical DNs (tests/unit/sim/test_sim_shared_cuda.cpp).
#pragma once

#include <cmath>
#include <cstdint>

#include "drivers/sim/optics_shared.h"
#include "sdk/core/host_device.h"

namespace sls::sim {

// --- Philox4x32-10 -----------------------------------------------------------------------

struct Philox4x32Counter {
  std::uint32_t v[4];
};

struct Philox4x32Key {
  std::uint32_t v[2];
};

SLS_HOST_DEVICE inline Philox4x32Counter philox4x32_10(Philox4x32Counter counter, Philox4x32Key key) {
  constexpr std::uint32_t kMultiplier0 = 0xD2511F53u;
  constexpr std::uint32_t kMultiplier1 = 0xCD9E8D57u;
  constexpr std::uint32_t kWeyl0 = 0x9E3779B9u;  // golden ratio
  constexpr std::uint32_t kWeyl1 = 0xBB67AE85u;  // sqrt(3) - 1
  std::uint32_t c0 = counter.v[0], c1 = counter.v[1], c2 = counter.v[2], c3 = counter.v[3];
  std::uint32_t k0 = key.v[0], k1 = key.v[1];
  for (int round = 0; round < 10; ++round) {
    if (round > 0) {
      k0 += kWeyl0;
      k1 += kWeyl1;
    }
    const std::uint64_t product0 = static_cast<std::uint64_t>(kMultiplier0) * c0;
    const std::uint64_t product1 = static_cast<std::uint64_t>(kMultiplier1) * c2;
    const std::uint32_t hi0 = static_cast<std::uint32_t>(product0 >> 32);
    const std::uint32_t lo0 = static_cast<std::uint32_t>(product0);
    const std::uint32_t hi1 = static_cast<std::uint32_t>(product1 >> 32);
    const std::uint32_t lo1 = static_cast<std::uint32_t>(product1);
    c0 = hi1 ^ c1 ^ k0;
    c1 = lo1;
    c2 = hi0 ^ c3 ^ k1;
    c3 = lo0;
  }
  return {{c0, c1, c2, c3}};
}

// Which pixel of which image of which frame a draw belongs to.
struct NoiseKey {
  std::uint64_t seed = 0;
  std::uint32_t frame = 0;
  std::uint32_t image = 0;  // index of the pattern image within the frame
  std::uint32_t pixel = 0;  // y * width + x
};

// Stream ids (8 bits). The renderer may use kUserStream and above for its own randomness.
constexpr std::uint32_t kShotNoiseStream = 0;
constexpr std::uint32_t kReadNoiseStream = 1;
constexpr std::uint32_t kUserStream = 16;

// A sequence of random numbers for one (key, stream): Philox blocks consumed four words at a
// time. Plain data; lives in registers in a kernel.
struct NoiseStream {
  Philox4x32Key key;
  Philox4x32Counter counter;  // v[3] = (stream << 24) | next block
  std::uint32_t words[4];
  int used;  // words of the current block already returned (4: fetch a new block)

  SLS_HOST_DEVICE std::uint32_t next_u32() {
    if (used >= 4) {
      const Philox4x32Counter block = philox4x32_10(counter, key);
      words[0] = block.v[0];
      words[1] = block.v[1];
      words[2] = block.v[2];
      words[3] = block.v[3];
      counter.v[3] = (counter.v[3] & 0xff000000u) | ((counter.v[3] + 1u) & 0x00ffffffu);
      used = 0;
    }
    return words[used++];
  }

  // Uniform in the open interval (0, 1): 52 random bits, centred in their cell, so never 0
  // or 1 (log and Box-Muller need that) and symmetric about 1/2.
  SLS_HOST_DEVICE double uniform() {
    const std::uint64_t hi = next_u32() >> 6;  // 26 bits
    const std::uint64_t lo = next_u32() >> 6;  // 26 bits
    return (static_cast<double>((hi << 26) | lo) + 0.5) * 2.220446049250313e-16;  // 2^-52
  }

  // Uniform float in (0, 1) from one word: 23 bits, centred.
  SLS_HOST_DEVICE float uniform_float() {
    return (static_cast<float>(next_u32() >> 9) + 0.5f) * 1.1920928955078125e-7f;  // 2^-23
  }

  // Standard normal by Box-Muller (cosine branch; the sine half is dropped to keep every
  // draw a fixed number of words).
  SLS_HOST_DEVICE double normal() {
    const double u1 = uniform();
    const double u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586476925 * u2);
  }
};

SLS_HOST_DEVICE inline NoiseStream make_noise_stream(const NoiseKey& key, std::uint32_t stream) {
  NoiseStream s;
  s.key = {{static_cast<std::uint32_t>(key.seed), static_cast<std::uint32_t>(key.seed >> 32)}};
  s.counter = {{key.pixel, key.image, key.frame, (stream & 0xffu) << 24}};
  s.words[0] = s.words[1] = s.words[2] = s.words[3] = 0;
  s.used = 4;
  return s;
}

// --- Poisson ---------------------------------------------------------------------------

// Means below this use inversion (sequential search, ~mean + 1 steps).
constexpr double kPoissonInversionBelow = 10.0;
// Means at or above this use the Gaussian N(mean, mean). Its first two moments are exact and
// its skewness error 1/sqrt(mean) is <= 0.032 there; the decoder's estimators (phase, Gray
// comparisons) are linear or threshold at the mean, where that skew does not bias them, and
// a pixel's read noise and 2.6 e-/DN quantisation blur the discreteness anyway. On the GPU
// it replaces PTRS's rejection loop (divergent warps) for almost every lit pixel.
constexpr double kPoissonGaussianFrom = 1000.0;

// log(k!) for integer k >= 0: the recurrence up to x = k + 1 >= 16, then Stirling's series
// to the x^-9 term (truncation < 2e-16 there). Host and device compute it the same way
// (std::lgamma is not thread-safe on glibc: it sets signgam).
SLS_HOST_DEVICE inline double log_factorial(double k) {
  double x = k + 1.0;
  double product = 1.0;
  while (x < 16.0) {
    product *= x;
    x += 1.0;
  }
  const double inverse = 1.0 / x;
  const double inverse2 = inverse * inverse;
  const double series =
      inverse * (1.0 / 12.0 - inverse2 * (1.0 / 360.0 - inverse2 * (1.0 / 1260.0 - inverse2 * (1.0 / 1680.0 - inverse2 / 1188.0))));
  return (x - 0.5) * std::log(x) - x + 0.91893853320467274178 + series - std::log(product);
}

// Hoermann's PTRS (transformed rejection with squeeze; Insurance: Mathematics and Economics
// 12, 1993), exact for mean >= 10; the constants are the paper's.
SLS_HOST_DEVICE inline double poisson_ptrs(NoiseStream& stream, double mean) {
  const double root = std::sqrt(mean);
  const double log_mean = std::log(mean);
  const double b = 0.931 + 2.53 * root;
  const double a = -0.059 + 0.02483 * b;
  const double inverse_alpha = 1.1239 + 1.1328 / (b - 3.4);
  const double v_r = 0.9277 - 3.6224 / (b - 2.0);
  for (;;) {
    const double u = stream.uniform() - 0.5;
    const double v = stream.uniform();
    const double us = 0.5 - std::fabs(u);
    const double k = std::floor((2.0 * a / us + b) * u + mean + 0.43);
    if (us >= 0.07 && v <= v_r) return k;
    if (k < 0.0 || (us < 0.013 && v > us)) continue;
    if (std::log(v) + std::log(inverse_alpha) - std::log(a / (us * us) + b) <= -mean + k * log_mean - log_factorial(k)) {
      return k;
    }
  }
}

// A Poisson(mean) sample (as a double; integral below kPoissonGaussianFrom). Non-positive or
// NaN means give 0.
SLS_HOST_DEVICE inline double poisson_sample(NoiseStream& stream, double mean) {
  if (!(mean > 0.0)) return 0.0;
  if (mean < kPoissonInversionBelow) {
    const double u = stream.uniform();
    double k = 0.0;
    double p = std::exp(-mean);
    double cdf = p;
    // The cap only matters if rounding leaves the summed CDF below u (u within 1e-16 of 1).
    while (u > cdf && k < 200.0) {
      k += 1.0;
      p *= mean / k;
      cdf += p;
    }
    return k;
  }
  if (mean < kPoissonGaussianFrom) return poisson_ptrs(stream, mean);
  return mean + std::sqrt(mean) * stream.normal();
}

// --- Sensor ------------------------------------------------------------------------------

SLS_HOST_DEVICE inline int sensor_max_dn(const SensorModel& sensor) {
  const int bits = sensor.bit_depth < 1 ? 1 : (sensor.bit_depth > 16 ? 16 : sensor.bit_depth);
  return (1 << bits) - 1;
}

// Analog DN (before quantisation) of a charge of `electrons`: gain, gamma above the black
// level (odd-symmetric below it, so read noise stays unbiased), black level.
SLS_HOST_DEVICE inline double sensor_analog_dn(const SensorModel& sensor, double electrons) {
  double signal = electrons / sensor.gain_e_per_dn;
  if (sensor.gamma != 1.0) {
    const double range = static_cast<double>(sensor_max_dn(sensor)) - sensor.black_level_dn;
    if (range > 0.0) {
      const double x = std::fabs(signal) / range;
      signal = std::copysign(range * std::pow(x, sensor.gamma), signal);
    }
  }
  return sensor.black_level_dn + signal;
}

// Rounds to the nearest DN and clamps to the ADC's range.
SLS_HOST_DEVICE inline int sensor_quantize(const SensorModel& sensor, double analog_dn) {
  const double max_dn = static_cast<double>(sensor_max_dn(sensor));
  const double rounded = std::floor(analog_dn + 0.5);
  if (!(rounded > 0.0)) return 0;  // also NaN
  if (rounded > max_dn) return sensor_max_dn(sensor);
  return static_cast<int>(rounded);
}

// The digital number a pixel reads for a mean signal of `electrons_mean` (photo-electrons
// plus ambient and dark signal, as the renderer computes them):
//   shot noise (Poisson) -> clip at the full well (the photodiode saturates) -> read noise
//   (Gaussian, sigma = read_noise_e) -> gain -> gamma -> black level -> round -> clamp to
//   0 .. 2^bit_depth - 1.
// Away from the clamps: mean = black + mu/g, variance = mu/g^2 + sigma_r^2/g^2 + 1/12 (the
// photon transfer curve; 1/12 DN^2 is the quantisation).
SLS_HOST_DEVICE inline int sensor_response(const SensorModel& sensor, double electrons_mean, const NoiseKey& key) {
  NoiseStream shot = make_noise_stream(key, kShotNoiseStream);
  double electrons = poisson_sample(shot, electrons_mean);
  if (electrons > sensor.full_well_e) electrons = sensor.full_well_e;
  NoiseStream read = make_noise_stream(key, kReadNoiseStream);
  electrons += sensor.read_noise_e * read.normal();
  return sensor_quantize(sensor, sensor_analog_dn(sensor, electrons));
}

// The same without noise: the expected signal, saturated and quantised (noise-free renders,
// ground truth, tests).
SLS_HOST_DEVICE inline int sensor_response_noiseless(const SensorModel& sensor, double electrons_mean) {
  double electrons = electrons_mean > 0.0 ? electrons_mean : 0.0;
  if (electrons > sensor.full_well_e) electrons = sensor.full_well_e;
  return sensor_quantize(sensor, sensor_analog_dn(sensor, electrons));
}

}  // namespace sls::sim
