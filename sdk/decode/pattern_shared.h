// The structured-light pattern vocabulary shared by the CPU and CUDA code (DESIGN.md
// section 6): what the DMD shows for one pattern, per projector pixel, and the irradiance a
// blurred projection of it puts at a continuous projector coordinate. The simulator's
// renderer calls these per camera pixel; the decoder reads the same descriptors.
//
// Coordinates follow sdk/core/camera_model_shared.h: projector pixel k (a column index for
// column patterns, a row index for row patterns) has its centre at the integer coordinate k
// and covers [k - 0.5, k + 0.5). Outside [0, extent) the mirrors send no light (level 0).
//
// Levels are what a DLPC350 shows in an 8-bit pattern: 0..255, displayed as a
// pulse-width-modulated duty cycle, so the time-averaged irradiance is level / 255 (the
// projector's black level and contrast are applied by the caller: drivers/sim/optics_shared.h).
//
// Gray code: column k carries the reflected binary code g(k) = k ^ (k >> 1); the pattern of
// bit b shows 255 where bit b of g(k) is 1 (0 when `inverted`). Bit b changes value at the
// odd multiples of 2^b, so its stripes are 2^(b+1) pixels wide. Bits >= s of g(k) are the
// Gray code of k >> s, so a set may stop at a coarse bit and still number periods of 2^s.
//
// Phase shift, step j of N, period P:
//   level(k) = round_half_up(127.5 + 127.5 * cos(2*pi*k/P + 2*pi*j/N))
// so with I_j = A + B*cos(phi + 2*pi*j/N) the decoder recovers phi(u) = 2*pi*u/P as
//   phi = atan2(-sum_j I_j sin(2*pi*j/N), sum_j I_j cos(2*pi*j/N)).
// Gray-code stripes change at pixel edges (k - 0.5), the phase wraps at pixel centres
// (u = n*P): the half-pixel offset is what the complementary Gray bit absorbs in decoding.
// The phase index m = (k*N + j*P) mod (P*N) is reduced in integers, and the exact quarter
// turns (cos = 0, +-1) are special-cased, so host and device round to the same level even
// where cos would land on a .5 tie (Niven: the only rational cosines of rational angles are
// 0, +-1/2 and +-1, and only cos = 0 gives a tie).
#pragma once

#include <cmath>
#include <cstdint>

#include "sdk/core/host_device.h"

namespace sls {

enum class PatternKind : std::int32_t {
  kWhite = 0,       // all mirrors on: reference for the albedo and the decode threshold
  kBlack = 1,       // all mirrors off: ambient + projector black level
  kGrayCode = 2,    // one bit of the reflected binary code, optionally inverted
  kPhaseShift = 3,  // one step of an N-step sinusoid of period P pixels
};

enum class PatternAxis : std::int32_t {
  kColumns = 0,  // the pattern varies along x (projector columns): encodes the column
  kRows = 1,     // the pattern varies along y (projector rows): encodes the row
};

// One projected pattern. Plain data so kernels take it by value. Fields that do not apply
// to the kind stay 0 (the JSON form omits them); the defaults are slscan's own conventions,
// the other fields say what other tools do differently (docs/pattern-descriptions.md).
struct PatternDesc {
  PatternKind kind = PatternKind::kWhite;
  PatternAxis axis = PatternAxis::kColumns;
  int extent = 0;         // projector pixels along the axis (width or height)
  int bit = 0;            // gray code: bit index b, 0 = finest
  bool inverted = false;  // gray code: the complementary pattern (255 - level)
  int step = 0;           // phase shift: j in [0, steps)
  int steps = 0;          // phase shift: N
  double period_px = 0;   // phase shift: P, in projector pixels along the axis (need not be an integer)
  // Phase shift: level(k) from cos(s * 2 pi k / P + 2 pi j / N + offset), s = -1 when
  // reversed (the phase falls along the axis, or the steps turn the other way).
  bool phase_reversed = false;
  double phase_offset_rad = 0;
  // Gray code over stripes rather than pixels: pixel k is in stripe
  // floor((k + 0.5 - gray_origin_px) / gray_unit_px) (unit 0 means 1: one stripe per pixel,
  // slscan's and OpenCV's code). A unit of P numbers phase periods, P/2 is the complementary
  // Gray code (one more bit, edges mid-period); the origin (<= 0) shifts the stripes.
  double gray_unit_px = 0;
  double gray_origin_px = 0;

  SLS_HOST_DEVICE bool operator==(const PatternDesc& o) const {
    return kind == o.kind && axis == o.axis && extent == o.extent && bit == o.bit && inverted == o.inverted &&
           step == o.step && steps == o.steps && period_px == o.period_px && phase_reversed == o.phase_reversed &&
           phase_offset_rad == o.phase_offset_rad && gray_unit_px == o.gray_unit_px &&
           gray_origin_px == o.gray_origin_px;
  }
  SLS_HOST_DEVICE bool operator!=(const PatternDesc& o) const { return !(*this == o); }
};

SLS_HOST_DEVICE inline std::uint32_t gray_encode(std::uint32_t value) { return value ^ (value >> 1); }

SLS_HOST_DEVICE inline std::uint32_t gray_decode(std::uint32_t code) {
  std::uint32_t value = code;
  for (std::uint32_t shift = 1; shift < 32; shift <<= 1) value ^= value >> shift;
  return value;
}

// The 8-bit level of step j of an N-step phase shift of integer period P at pixel k, in
// the default sign (+1) or reversed (-1), without offset: reduced exactly in integers.
SLS_HOST_DEVICE inline int phase_shift_level(int k, int step, int steps, int period_px, int sign = 1) {
  const std::int64_t turn = static_cast<std::int64_t>(period_px) * steps;
  if (turn <= 0) return 0;
  std::int64_t m =
      (sign * static_cast<std::int64_t>(k) * steps + static_cast<std::int64_t>(step) * period_px) % turn;
  if (m < 0) m += turn;
  if (m == 0) return 255;                      // cos = 1
  if (2 * m == turn) return 0;                 // cos = -1
  if (4 * m == turn || 4 * m == 3 * turn) return 128;  // cos = 0: 127.5 rounds half up
  const double angle = 6.283185307179586476925 * (static_cast<double>(m) / static_cast<double>(turn));
  return static_cast<int>(std::floor(127.5 + 127.5 * std::cos(angle) + 0.5));
}

// Any phase pattern: integer periods without offset take the exact path above; others (a
// period of 1024/90 px, an offset) round 127.5 + 127.5 cos(angle) in double, the angle's
// turns reduced to [0, 1) first so that large k lose no precision.
SLS_HOST_DEVICE inline int phase_pattern_level(const PatternDesc& d, int k) {
  const int sign = d.phase_reversed ? -1 : 1;
  const double whole = std::floor(d.period_px);
  if (d.phase_offset_rad == 0.0 && whole == d.period_px && d.period_px >= 1.0 && d.period_px < 2147483647.0) {
    return phase_shift_level(k, d.step, d.steps, static_cast<int>(whole), sign);
  }
  if (!(d.period_px > 0.0) || d.steps <= 0) return 0;
  double turns = static_cast<double>(sign * k) / d.period_px + static_cast<double>(d.step) / d.steps +
                 d.phase_offset_rad / 6.283185307179586476925;
  turns -= std::floor(turns);
  return static_cast<int>(std::floor(127.5 + 127.5 * std::cos(6.283185307179586476925 * turns) + 0.5));
}

// The stripe of pixel k in a Gray code over stripes (PatternDesc::gray_unit_px); -1 left of
// the origin.
SLS_HOST_DEVICE inline std::int64_t gray_stripe_of(const PatternDesc& d, int k) {
  if (d.gray_unit_px == 0.0 && d.gray_origin_px == 0.0) return k;
  const double unit = d.gray_unit_px > 0.0 ? d.gray_unit_px : 1.0;
  return static_cast<std::int64_t>(std::floor((static_cast<double>(k) + 0.5 - d.gray_origin_px) / unit));
}

// The DMD level (0..255) of projector pixel `index` along the pattern's axis; 0 outside
// [0, extent) where there is no mirror.
SLS_HOST_DEVICE inline int pattern_pixel_value(const PatternDesc& d, int index) {
  if (index < 0 || index >= d.extent) return 0;
  switch (d.kind) {
    case PatternKind::kWhite:
      return 255;
    case PatternKind::kBlack:
      return 0;
    case PatternKind::kGrayCode: {
      const std::int64_t stripe = gray_stripe_of(d, index);
      if (d.bit < 0 || d.bit > 30 || stripe < 0) return d.inverted ? 255 : 0;
      const std::uint32_t on = (gray_encode(static_cast<std::uint32_t>(stripe)) >> d.bit) & 1u;
      return (on != 0u) != d.inverted ? 255 : 0;
    }
    case PatternKind::kPhaseShift:
      return phase_pattern_level(d, index);
  }
  return 0;
}

// Levels read from a table (one byte per pixel along the axis, e.g. sls::pattern_levels()
// copied to the device): the blurred evaluation needs ~2*8.5*sigma levels per call, and a
// table spares a cos per level for phase patterns.
struct PatternLevelTable {
  const std::uint8_t* levels = nullptr;
  int extent = 0;
};

namespace detail {

struct DescLevels {
  const PatternDesc* desc;
  SLS_HOST_DEVICE int operator()(int k) const { return pattern_pixel_value(*desc, k); }
};

// The light a projector emits for each DMD level: response(level) in [0, 255] (a projector
// that is not linear in its levels, e.g. video gamma).
template <typename Levels, typename Response>
struct ResponseLevels {
  Levels level;
  Response response;
  SLS_HOST_DEVICE double operator()(int k) const { return response(level(k)); }
};

struct TableLevels {
  PatternLevelTable table;
  SLS_HOST_DEVICE int operator()(int k) const {
    return (k >= 0 && k < table.extent) ? static_cast<int>(table.levels[k]) : 0;
  }
};

// How far (in sigmas) the Gaussian is followed: beyond it the tail mass Phi(-t) is below the
// type's resolution (Phi(-8.5) = 9.5e-18 for double, Phi(-5.5) = 1.9e-8 for float), so the
// truncated sum equals the full convolution to rounding.
SLS_HOST_DEVICE inline double tail_sigmas(double) { return 8.5; }
SLS_HOST_DEVICE inline float tail_sigmas(float) { return 5.5f; }

template <typename T>
SLS_HOST_DEVICE inline T min_of(T a, T b) { return b < a ? b : a; }
template <typename T>
SLS_HOST_DEVICE inline T max_of(T a, T b) { return a < b ? b : a; }

template <typename T, typename Levels>
SLS_HOST_DEVICE inline T sharp_value(const Levels& level, int extent, T u) {
  const T k = std::floor(u + T(0.5));  // pixel k covers [k - 0.5, k + 0.5)
  if (!(k >= T(0) && k < static_cast<T>(extent))) return T(0);
  return static_cast<T>(level(static_cast<int>(k))) / T(255);
}

// The piecewise-constant profile L_k convolved with a Gaussian of sigma, at u:
//   I(u) = sum_k L_k/255 * [Phi((k+0.5-u)/sigma) - Phi((k-0.5-u)/sigma)].
// Summation by parts turns it into a sum over the pixel edges e_k = k + 0.5:
//   I(u) = L_{k1+1}/255 + sum_{k=k0..k1} (L_k - L_{k+1})/255 * Phi((e_k - u)/sigma)
// for the edges within reach, where the edges right of the window have Phi = 1 (they
// telescope into L_{k1+1}) and those left of it Phi = 0. Only edges where the level changes
// cost an erfc, so Gray-code and reference patterns are cheap at any sigma.
template <typename T, typename Levels>
SLS_HOST_DEVICE inline T blurred_value(const Levels& level, int extent, T u, T sigma) {
  if (!(u == u)) return T(0);
  if (!(sigma > T(0))) return sharp_value(level, extent, u);
  const T reach = sigma * tail_sigmas(T(0));
  // Edge indices k (edge at k + 0.5) with |k + 0.5 - u| <= reach; outside [-1, extent - 1]
  // the level is 0 on both sides, so no edge there.
  const T lo = max_of(std::ceil(u - reach - T(0.5)), T(-1));
  const T hi = min_of(std::floor(u + reach - T(0.5)), static_cast<T>(extent - 1));
  if (!(lo <= hi)) return sharp_value(level, extent, u);  // flat within reach
  const int k0 = static_cast<int>(lo);
  const int k1 = static_cast<int>(hi);
  const T scale = T(1) / (sigma * T(1.41421356237309504880));
  auto current = level(k0);  // int levels, or the light of a non-linear projector
  T sum = T(0);
  for (int k = k0; k <= k1; ++k) {
    const auto next = level(k + 1);
    if (next != current) {
      // Phi(z) = erfc(-z / sqrt(2)) / 2, accurate in both tails.
      const T z = (static_cast<T>(k) + T(0.5) - u) * scale;
      sum += static_cast<T>(current - next) * (T(0.5) * std::erfc(-z));
    }
    current = next;
  }
  return (static_cast<T>(current) + sum) / T(255);
}

}  // namespace detail

// The sharp (unblurred) irradiance in [0, 1] at continuous coordinate u along the axis.
template <typename T>
SLS_HOST_DEVICE inline T pattern_value_sharp(const PatternDesc& d, T u) {
  return detail::sharp_value(detail::DescLevels{&d}, d.extent, u);
}

// The irradiance in [0, 1] at continuous projector coordinate u (pixels along the pattern's
// axis) of the DMD pattern blurred by a Gaussian of sigma_px (projector pixels along the
// same axis): the exact convolution of the piecewise-constant levels with the Gaussian.
// sigma_px <= 0 gives the sharp value. T is double or float.
template <typename T>
SLS_HOST_DEVICE inline T pattern_value_blurred(const PatternDesc& d, T u, T sigma_px) {
  return detail::blurred_value(detail::DescLevels{&d}, d.extent, u, sigma_px);
}

// The same for a projector whose emitted light is response(level) (in [0, 255]) rather than
// the level itself: the response applies to each DMD pixel, before the lens blurs them.
template <typename T, typename Response>
SLS_HOST_DEVICE inline T pattern_value_blurred(const PatternDesc& d, T u, T sigma_px, const Response& response) {
  return detail::blurred_value(detail::ResponseLevels<detail::DescLevels, Response>{{&d}, response}, d.extent, u,
                               sigma_px);
}

// The same over a precomputed level table (identical result: the levels are the same).
template <typename T>
SLS_HOST_DEVICE inline T pattern_value_blurred(const PatternLevelTable& table, T u, T sigma_px) {
  return detail::blurred_value(detail::TableLevels{table}, table.extent, u, sigma_px);
}

template <typename T, typename Response>
SLS_HOST_DEVICE inline T pattern_value_blurred(const PatternLevelTable& table, T u, T sigma_px,
                                               const Response& response) {
  return detail::blurred_value(detail::ResponseLevels<detail::TableLevels, Response>{{table}, response}, table.extent,
                               u, sigma_px);
}

}  // namespace sls
