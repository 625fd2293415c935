// Per-pixel decoding of a Gray code + phase-shift stack into projector coordinates, shared by
// the CPU and CUDA decoders (DESIGN.md section 6). Plain structs, no Eigen, no virtuals.
//
// Conventions (sdk/decode/pattern_shared.h): projector pixel k has its centre at coordinate
// k and covers [k - 0.5, k + 0.5). Gray bit b of column k is bit b of g(k) = k ^ (k >> 1);
// phase step j of N, period P: I_j = A + B cos(phi + 2 pi j / N) with phi = 2 pi u / P, so
//   phi = atan2(-sum_j I_j sin(2 pi j/N), sum_j I_j cos(2 pi j/N)),   B = (2/N) |(C, S)|.
//
// Unwrapping (the complementary Gray code of Zhang et al. 2012, written as a rounding):
// the projected Gray bits lowest..highest number stripes of W = 2^lowest pixels; stripe j
// covers [W j - 0.5, W j + W - 0.5). The default set stops at W = P/2 (the "complementary"
// bit: its edges lie mid-period, where the phase is far from its wrap). With the stripe's
// centre u_g = W j + (W - 1)/2 and the wrapped coordinate u_w = phi P / 2 pi in [0, P),
//   n = round((u_g - u_w) / P),   u = n P + u_w.
// |u_g - u| <= W/2 = P/4 inside a correctly decoded stripe, so the rounding has a quarter
// period of margin. Near a stripe edge a blurred or noisy pair may decide the bit that
// changes there either way; the Gray code's one-bit-per-edge property makes the wrong
// decision the neighbouring stripe, which moves u_g by W but keeps |u_g - u| <= W/2 + (the
// distance to the edge), still inside the margin: no pixel jumps by a whole period. In other
// words, the finest bit picks which of the two periods around the phase wrap agrees with the
// phase. The result is then checked against the decoded stripe (consistency flag).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "sdk/core/host_device.h"
#include "sdk/decode/pattern_shared.h"

namespace sls {

constexpr int kDecodeMaxGrayBits = 24;
constexpr int kDecodeMaxPhaseSteps = 32;

// Bit flags of DecodedFrame::mask. kDecodeOk alone means projector coordinates and depth are
// valid; kDecodeOutOfRange alone means the coordinates are valid but triangulation rejected
// the point. Any other flag: the coordinates are NaN and the depth 0.
enum DecodeMaskBits : std::uint8_t {
  kDecodeOk = 1u,
  kDecodeLowModulation = 2u,  // fringe too weak against the noise (blur, grazing light)
  kDecodeSaturated = 4u,      // a sample at or above the saturation level
  kDecodeInconsistent = 8u,   // Gray code and phase disagree, or too many ambiguous bits
  kDecodeShadow = 16u,        // white - black contrast too low (shadow, off the projector)
  kDecodeOutOfRange = 32u,    // triangulation: depth range, small angle, no convergence
};

// Where one axis' patterns sit in the stack. extent == 0: the axis is not coded.
struct AxisCode {
  int extent = 0;                // projector pixels along the axis
  int gray_count = 0;            // bits gray_lowest_bit .. gray_lowest_bit + gray_count - 1
  int gray_lowest_bit = 0;
  int gray_index[kDecodeMaxGrayBits] = {};          // stack index of bit (lowest + i)
  int gray_inverse_index[kDecodeMaxGrayBits] = {};  // its complement, -1 when not projected
  int phase_count = 0;           // phase images (N)
  int phase_period_px = 0;
  int phase_index[kDecodeMaxPhaseSteps] = {};
  float phase_cos[kDecodeMaxPhaseSteps] = {};  // cos(2 pi j / N) of that image's step j
  float phase_sin[kDecodeMaxPhaseSteps] = {};
};

struct DecodeLayout {
  int pattern_count = 0;
  int white_index = -1;  // -1: not in the set
  int black_index = -1;
  AxisCode axes[2];      // [0] columns (u), [1] rows (v)
};

// Thresholds in the form the per-pixel code wants (see DecodeOptions in decoder.h for the
// meaning and defaults).
struct DecodeThresholds {
  float saturation_dn = 4013.0f;
  float black_level_dn = 32.0f;
  float inverse_gain = 1.0f / 2.6f;  // DN per electron
  float read_noise_variance = 0.85f; // DN^2 (read noise + quantisation)
  float shadow_min_contrast_dn = 16.0f;
  float shadow_contrast_sigma = 6.0f;
  float gray_margin_sigma = 3.0f;
  float min_modulation_ratio = 0.25f;
  float max_phase_sigma_px = 0.2f;
  float consistency_tolerance_px = 2.0f;
  float confidence_sigma_px = 0.05f;
};

struct DecodeParams {
  DecodeLayout layout;
  DecodeThresholds thresholds;
};

// Sample accessors: value of stack image k at one pixel.
// Planes laid out one after another with a fixed stride (a device-resident stack).
struct StridedStackSamples {
  const std::uint16_t* base;
  std::size_t plane_stride;  // elements from one image to the next
  std::size_t pixel;         // element index within an image
  SLS_HOST_DEVICE float operator()(int k) const {
    return static_cast<float>(base[static_cast<std::size_t>(k) * plane_stride + pixel]);
  }
};

// One pointer per image (host images that live in separate buffers).
struct PlanePointerSamples {
  const std::uint16_t* const* planes;
  std::size_t pixel;
  SLS_HOST_DEVICE float operator()(int k) const { return static_cast<float>(planes[k][pixel]); }
};

// Temporal noise variance (DN^2) of a sample of `value` DN: shot noise of the signal above
// the black level plus read noise (the photon transfer model of a linear camera).
SLS_HOST_DEVICE inline float sample_variance(const DecodeThresholds& t, float value) {
  const float signal = value - t.black_level_dn;
  return (signal > 0.0f ? signal * t.inverse_gain : 0.0f) + t.read_noise_variance;
}

// The shadow test: a contrast between a bright and a dark sample that stands out of their
// noise (and above the floor for cameras whose noise model is unknown).
SLS_HOST_DEVICE inline bool contrast_above_noise(const DecodeThresholds& t, float bright, float dark, float contrast) {
  const float sigma = std::sqrt(sample_variance(t, bright) + sample_variance(t, dark));
  return contrast >= t.shadow_min_contrast_dn && contrast >= t.shadow_contrast_sigma * sigma;
}

struct AxisDecode {
  float coordinate;  // projector pixels; NaN when flags != 0
  float sigma_px;    // predicted 1-sigma noise of the coordinate
  std::uint8_t flags;
};

// The period index from the Gray stripe and the wrapped coordinate (see the file comment).
SLS_HOST_DEVICE inline float unwrap_coordinate(float stripe_centre, float wrapped, float period) {
  const float n = std::floor((stripe_centre - wrapped) / period + 0.5f);
  return n * period + wrapped;
}

// Distance from u to stripe j's extent [W j - 0.5, W j + W - 0.5]; 0 inside.
SLS_HOST_DEVICE inline float distance_to_stripe(float u, int stripe, float width) {
  const float lo = static_cast<float>(stripe) * width - 0.5f;
  const float hi = lo + width;
  return u < lo ? lo - u : (u > hi ? u - hi : 0.0f);
}

// Decodes one axis. `reference` is (white + black) / 2 (the threshold for Gray bits without a
// projected complement), `contrast` white - black.
template <typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_axis(const AxisCode& a, const DecodeThresholds& t, const Samples& samples,
                                              float reference, float contrast) {
  AxisDecode out{NAN, 0.0f, 0u};
  std::uint8_t flags = 0u;
  // Gray bits: each a comparison of a pattern with its complement (blur and albedo move no
  // edge of a complementary pair); ambiguous where the difference is within the noise.
  std::uint32_t code = 0u;
  int ambiguous = 0;
  int ambiguous_bit = -1;
  for (int i = 0; i < a.gray_count; ++i) {
    const float p = samples(a.gray_index[i]);
    float q = reference;
    float variance = sample_variance(t, p);
    if (a.gray_inverse_index[i] >= 0) {
      q = samples(a.gray_inverse_index[i]);
      variance += sample_variance(t, q);
      if (q >= t.saturation_dn) flags |= kDecodeSaturated;
    }
    if (p >= t.saturation_dn) flags |= kDecodeSaturated;
    const float d = p - q;
    if (d > 0.0f) code |= 1u << i;
    if (std::fabs(d) <= t.gray_margin_sigma * std::sqrt(variance)) {
      ++ambiguous;
      ambiguous_bit = i;
    }
  }
  // Only one bit changes at any stripe edge and edges of different bits are >= W apart, so
  // two ambiguous bits mean there is no usable signal, not an edge.
  if (ambiguous > 1) flags |= kDecodeInconsistent;
  const float width = static_cast<float>(1 << a.gray_lowest_bit);
  const std::uint32_t stripe_value = gray_decode(code);
  const int stripe = static_cast<int>(stripe_value);
  const float stripe_centre = static_cast<float>(stripe) * width + 0.5f * (width - 1.0f);

  float u = stripe_centre;
  float sigma = width * 0.288675135f;  // a uniform stripe: W / sqrt(12)
  if (a.phase_count > 0) {
    float c = 0.0f, s = 0.0f, sum = 0.0f;
    for (int i = 0; i < a.phase_count; ++i) {
      const float value = samples(a.phase_index[i]);
      if (value >= t.saturation_dn) flags |= kDecodeSaturated;
      c += value * a.phase_cos[i];
      s += value * a.phase_sin[i];
      sum += value;
    }
    const float n = static_cast<float>(a.phase_count);
    const float mean = sum / n;
    const float modulation = (2.0f / n) * std::sqrt(c * c + s * s);
    const float period = static_cast<float>(a.phase_period_px);
    float phi = std::atan2(-s, c);
    if (phi < 0.0f) phi += 6.28318530717958648f;
    float wrapped = phi * (period / 6.28318530717958648f);
    if (wrapped >= period) wrapped -= period;  // phi rounded up to 2 pi
    // Phase noise of N-step phase shifting: sigma_phi = sqrt(2/N) sigma_I / B.
    const float sigma_intensity = std::sqrt(sample_variance(t, mean));
    sigma = modulation > 0.0f
                ? period * 0.159154943f * std::sqrt(2.0f / n) * sigma_intensity / modulation
                : INFINITY;
    if (!(modulation >= t.min_modulation_ratio * 0.5f * contrast) || !(sigma <= t.max_phase_sigma_px)) {
      flags |= kDecodeLowModulation;
    }
    u = unwrap_coordinate(stripe_centre, wrapped, period);
    // Consistency: the unwrapped coordinate must lie in the decoded stripe (or, when one bit
    // was ambiguous, in the stripe its other decision names), up to the tolerance.
    if (a.gray_count > 0) {
      float distance = distance_to_stripe(u, stripe, width);
      if (distance > t.consistency_tolerance_px && ambiguous == 1) {
        const int other = static_cast<int>(gray_decode(code ^ (1u << ambiguous_bit)));
        const float other_distance = distance_to_stripe(u, other, width);
        distance = other_distance < distance ? other_distance : distance;
      }
      if (distance > t.consistency_tolerance_px) flags |= kDecodeInconsistent;
    }
  }
  if (!(u >= -0.5f - t.consistency_tolerance_px &&
        u <= static_cast<float>(a.extent) - 0.5f + t.consistency_tolerance_px)) {
    flags |= kDecodeInconsistent;
  }
  out.flags = flags;
  out.sigma_px = sigma;
  if (flags == 0u) out.coordinate = u;
  return out;
}

struct PixelDecode {
  float u;           // projector column coordinate, NaN when not decoded
  float v;           // projector row coordinate, NaN when not decoded or rows not coded
  float confidence;  // [0, 1], 0 when not decoded
  std::uint8_t mask; // DecodeMaskBits (kDecodeOk set when both coded axes decoded)
};

// Decodes one pixel: references (shadow test), then each coded axis. Triangulation is
// separate (triangulate_shared.h) and may add kDecodeOutOfRange.
template <typename Samples>
SLS_HOST_DEVICE inline PixelDecode decode_pixel(const DecodeParams& p, const Samples& samples) {
  const DecodeLayout& layout = p.layout;
  const DecodeThresholds& t = p.thresholds;
  PixelDecode out{NAN, NAN, 0.0f, 0u};
  std::uint8_t flags = 0u;
  float reference = 0.0f;
  float contrast = 0.0f;
  if (layout.white_index >= 0 && layout.black_index >= 0) {
    const float white = samples(layout.white_index);
    const float black = samples(layout.black_index);
    if (white >= t.saturation_dn) flags |= kDecodeSaturated;
    reference = 0.5f * (white + black);
    contrast = white - black;
    if (!contrast_above_noise(t, white, black, contrast)) flags |= kDecodeShadow;
  } else {
    // No references: the contrast of the first complementary Gray pair stands in, since away
    // from its edges |pattern - inverse| is the full white - black contrast.
    const AxisCode& a = layout.axes[layout.axes[0].extent > 0 ? 0 : 1];
    if (a.gray_count > 0 && a.gray_inverse_index[a.gray_count - 1] >= 0) {
      const float p0 = samples(a.gray_index[a.gray_count - 1]);
      const float q0 = samples(a.gray_inverse_index[a.gray_count - 1]);
      reference = 0.5f * (p0 + q0);
      contrast = std::fabs(p0 - q0);
      if (!contrast_above_noise(t, p0, q0, contrast)) flags |= kDecodeShadow;
    }
  }
  float worst_sigma = 0.0f;
  if (flags == 0u) {
    for (int axis = 0; axis < 2; ++axis) {
      const AxisCode& a = layout.axes[axis];
      if (a.extent <= 0) continue;
      const AxisDecode d = decode_axis(a, t, samples, reference, contrast);
      flags |= d.flags;
      if (d.sigma_px > worst_sigma) worst_sigma = d.sigma_px;
      if (axis == 0) {
        out.u = d.coordinate;
      } else {
        out.v = d.coordinate;
      }
    }
  }
  if (flags != 0u) {
    out.u = NAN;
    out.v = NAN;
    out.mask = flags;
    return out;
  }
  // Confidence: 1 for a noise-free coordinate, 1/2 where the predicted noise equals
  // confidence_sigma_px, falling as 1/sigma^2 beyond.
  const float r = worst_sigma / t.confidence_sigma_px;
  out.confidence = 1.0f / (1.0f + r * r);
  out.mask = kDecodeOk;
  return out;
}

}  // namespace sls
