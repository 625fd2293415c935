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
//
// The same rounding serves the other families (pattern_set.h): a Gray code over stripes of
// unit W0 px from an origin o (stripe j covers [o - 0.5 + W j, o - 0.5 + W (j + 1)), W =
// W0 2^lowest) need not be aligned with the phase wraps, since the rounding only needs u_g
// within P/2 of u; a Gray code numbering whole periods (W = P) has no margin at its edges,
// so there the ambiguous bit's two decisions are both unwrapped and the one whose stripe
// holds its result wins. Several periods on one axis unwrap coarse to fine, each from the
// coarser coordinate; the phase's sign and offset map psi = s 2 pi u / P + offset back to u.
//
// Heterodyne and micro phase-shifting sets have no Gray code: their axes unwrap by the beats
// of their periods or by a search over the periods (multi_frequency_shared.h).
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "sdk/core/host_device.h"
#include "sdk/decode/pattern_shared.h"

namespace sls {

constexpr int kDecodeMaxGrayBits = 24;
constexpr int kDecodeMaxPhaseSteps = 32;
// Phase shifts of distinct periods on one axis (multi-period sets unwrap coarse to fine;
// heterodyne sets beat two or three).
constexpr int kDecodeMaxPhaseGroups = 3;
// Single images of the other periods of a micro phase-shifting axis.
constexpr int kDecodeMaxMicroSingles = 10;

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

// One phase shift of one period: N images, their steps' cos/sin, and how the phase maps
// to the coordinate (sign, offset: PatternDesc).
struct PhaseGroup {
  int count = 0;        // N
  float period_px = 0.0f;
  float sign = 1.0f;    // -1: reversed
  float offset_rad = 0.0f;
  int index[kDecodeMaxPhaseSteps] = {};
  float cos_step[kDecodeMaxPhaseSteps] = {};  // cos(2 pi j / N) of that image's step j
  float sin_step[kDecodeMaxPhaseSteps] = {};
  // Per group, not per pixel (set_phase_group_scales, once the group is complete): B = 2/N |(C, S)|
  // and the coordinate's noise P / 2 pi sqrt(2/N) sigma_I / B, the same float operations.
  float modulation_scale = 0.0f;  // 2 / N
  float sigma_scale = 0.0f;       // P / 2 pi * sqrt(2 / N)
};

SLS_HOST_DEVICE inline void set_phase_group_scales(PhaseGroup& g) {
  const float n = static_cast<float>(g.count);
  g.modulation_scale = 2.0f / n;
  g.sigma_scale = g.period_px * 0.159154943f * std::sqrt(2.0f / n);
}

// How Gray bits without a projected complement are thresholded.
enum GrayThreshold : std::int32_t {
  kGrayThresholdReference = 0,  // (white + black) / 2 (the complement where there is one)
  kGrayThresholdPhaseMean = 1,  // the mean of the axis' first phase group (its A)
};

// How a set's axes are unwrapped (from its PatternSetKind).
enum DecodeUnwrap : std::int32_t {
  kUnwrapGrayPhase = 0,   // a Gray code (or a one-period cue), then coarse-to-fine periods
  kUnwrapHeterodyne = 1,  // two or three periods by their beats (multi_frequency_shared.h)
  kUnwrapMicroPhase = 2,  // one N-step period and single images of nearby periods, searched
};

// One single image of a micro phase-shifting axis: level = cos(sign 2 pi u / P + shift).
struct MicroSingle {
  int index = 0;
  float period_px = 0.0f;
  float sign = 1.0f;
  float shift_rad = 0.0f;  // 2 pi j / N + offset
};

// Where one axis' patterns sit in the stack. extent == 0: the axis is not coded.
struct AxisCode {
  int extent = 0;                // projector pixels along the axis
  int gray_count = 0;            // bits gray_lowest_bit .. gray_lowest_bit + gray_count - 1
  int gray_lowest_bit = 0;
  float gray_unit_px = 1.0f;     // stripe unit of the code (PatternDesc::gray_unit_px)
  float gray_origin_px = 0.0f;
  int gray_threshold = kGrayThresholdReference;
  int gray_index[kDecodeMaxGrayBits] = {};          // stack index of bit (lowest + i)
  int gray_inverse_index[kDecodeMaxGrayBits] = {};  // its complement, -1 when not projected
  int phase_group_count = 0;     // coarsest period first: each unwraps the next
  PhaseGroup phase[kDecodeMaxPhaseGroups];
  // Micro phase shifting: phase[0] is the N-step period, these the single images.
  int micro_count = 0;
  MicroSingle micro[kDecodeMaxMicroSingles];
};

struct DecodeLayout {
  int unwrap = kUnwrapGrayPhase;  // DecodeUnwrap, the same for both axes
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
// Planes laid out one after another with a fixed stride (a device-resident stack). The stride
// is 32-bit (a plane of fewer than 2^32 pixels; launch_decode_cuda checks it): image k's offset
// is then one widening multiply, not a 64-bit one, for each of a pixel's ~22 samples.
struct StridedStackSamples {
  const std::uint16_t* pixel_base;  // the pixel's element in image 0
  std::uint32_t plane_stride;       // elements from one image to the next
  SLS_HOST_DEVICE float operator()(int k) const {
    return static_cast<float>(pixel_base[static_cast<std::uint64_t>(static_cast<std::uint32_t>(k)) * plane_stride]);
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
// Compared squared: a square root costs the GPU ~8 instructions, and this runs on every pixel.
SLS_HOST_DEVICE inline bool contrast_above_noise(const DecodeThresholds& t, float bright, float dark, float contrast) {
  const float variance = sample_variance(t, bright) + sample_variance(t, dark);
  return contrast >= t.shadow_min_contrast_dn && contrast >= 0.0f &&
         contrast * contrast >= t.shadow_contrast_sigma * t.shadow_contrast_sigma * variance;
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

// Stripe j's extent along the axis: the pixels whose centres k satisfy
// j W <= k + 0.5 - o < (j + 1) W (pattern_shared.h), edges at pixel edges.
struct StripeExtent {
  float lo, hi;
};

SLS_HOST_DEVICE inline StripeExtent stripe_extent(int stripe, float width, float origin) {
  const float first = std::ceil(origin - 0.5f + static_cast<float>(stripe) * width);
  const float end = std::ceil(origin - 0.5f + static_cast<float>(stripe + 1) * width);
  return {first - 0.5f, end - 0.5f};
}

// Distance from u to an extent; 0 inside.
SLS_HOST_DEVICE inline float distance_to_stripe(float u, StripeExtent e) {
  return u < e.lo ? e.lo - u : (u > e.hi ? u - e.hi : 0.0f);
}

// The period of the wrapped coordinate that a stripe agrees with: the rounding from the
// stripe's centre, or a neighbouring period when that lands closer to the stripe (stripes as
// wide as the period, whose edges need not fall on the wraps).
SLS_HOST_DEVICE inline float unwrap_in_stripe(StripeExtent e, float wrapped, float period, float* distance) {
  float u = unwrap_coordinate(0.5f * (e.lo + e.hi), wrapped, period);
  float best = distance_to_stripe(u, e);
  for (int side = -1; side <= 1; side += 2) {
    const float candidate = u + static_cast<float>(side) * period;
    const float d = distance_to_stripe(candidate, e);
    if (d < best) {
      best = d;
      u = candidate;
    }
  }
  *distance = best;
  return u;
}

// One phase group's wrapped coordinate in [0, P), its fringe amplitude B, mean A, and the
// predicted 1-sigma noise of the coordinate.
struct WrappedPhase {
  float wrapped;
  float modulation;
  float mean;
  float sigma_px;
  bool saturated;
};

template <typename Samples>
SLS_HOST_DEVICE inline WrappedPhase wrapped_phase(const PhaseGroup& g, const DecodeThresholds& t,
                                                  const Samples& samples) {
  WrappedPhase out{0.0f, 0.0f, 0.0f, INFINITY, false};
  float c = 0.0f, s = 0.0f, sum = 0.0f;
  for (int i = 0; i < g.count; ++i) {
    const float value = samples(g.index[i]);
    if (value >= t.saturation_dn) out.saturated = true;
    c += value * g.cos_step[i];
    s += value * g.sin_step[i];
    sum += value;
  }
  out.mean = sum / static_cast<float>(g.count);
  out.modulation = g.modulation_scale * std::sqrt(c * c + s * s);
  const float inverse_two_pi = 0.159154943f;
  // psi = sign * 2 pi u / P + offset  =>  u = P / 2 pi * sign * (psi - offset), mod P.
  float turns = g.sign * (std::atan2(-s, c) - g.offset_rad) * inverse_two_pi;
  turns -= std::floor(turns);
  float wrapped = turns * g.period_px;
  if (wrapped >= g.period_px) wrapped -= g.period_px;  // turns rounded up to 1
  out.wrapped = wrapped;
  // Phase noise of N-step phase shifting: sigma_phi = sqrt(2/N) sigma_I / B.
  const float sigma_intensity = std::sqrt(sample_variance(t, out.mean));
  if (out.modulation > 0.0f) {
    out.sigma_px = g.sigma_scale * sigma_intensity / out.modulation;
  }
  return out;
}

// A decoded coordinate beyond the axis by more than the consistency tolerance: a misdecode.
SLS_HOST_DEVICE inline bool off_axis(const AxisCode& a, const DecodeThresholds& t, float u) {
  return !(u >= -0.5f - t.consistency_tolerance_px &&
           u <= static_cast<float>(a.extent) - 0.5f + t.consistency_tolerance_px);
}

// A fringe weaker than its share of the contrast, or whose coordinate is noisier than
// max_sigma_px.
SLS_HOST_DEVICE inline bool weak_fringe(const WrappedPhase& w, const DecodeThresholds& t, float contrast,
                                        float max_sigma_px) {
  return !(w.modulation >= t.min_modulation_ratio * 0.5f * contrast) || !(w.sigma_px <= max_sigma_px);
}

// The other unwrappings (multi_frequency_shared.h, included at the end of this file).
template <typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_heterodyne_axis(const AxisCode& a, const DecodeThresholds& t,
                                                         const Samples& samples, float contrast);
template <typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_micro_phase_axis(const AxisCode& a, const DecodeThresholds& t,
                                                          const Samples& samples, float contrast);

// Decodes one axis. `reference` is (white + black) / 2 (the threshold for Gray bits without a
// projected complement), `contrast` white - black.
template <typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_axis(const AxisCode& a, const DecodeThresholds& t, const Samples& samples,
                                              float reference, float contrast) {
  AxisDecode out{NAN, 0.0f, 0u};
  std::uint8_t flags = 0u;
  WrappedPhase phases[kDecodeMaxPhaseGroups];
  for (int g = 0; g < a.phase_group_count; ++g) {
    phases[g] = wrapped_phase(a.phase[g], t, samples);
    if (phases[g].saturated) flags |= kDecodeSaturated;
  }
  if (a.gray_threshold == kGrayThresholdPhaseMean && a.phase_group_count > 0) reference = phases[0].mean;
  // Gray bits: each a comparison of a pattern with its complement (blur and albedo move no
  // edge of a complementary pair) or with the threshold; ambiguous where the difference is
  // within the noise.
  std::uint32_t code = 0u;
  const float margin_squared = t.gray_margin_sigma * t.gray_margin_sigma;
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
    if (d * d <= margin_squared * variance) {  // |d| <= margin sigma, without a square root per bit
      ++ambiguous;
      ambiguous_bit = i;
    }
  }
  // Only one bit changes at any stripe edge and edges of different bits are >= W apart, so
  // two ambiguous bits mean there is no usable signal, not an edge.
  if (ambiguous > 1) flags |= kDecodeInconsistent;
  const float width = a.gray_unit_px * static_cast<float>(1 << a.gray_lowest_bit);
  const int stripe = static_cast<int>(gray_decode(code));
  const int other = ambiguous == 1 ? static_cast<int>(gray_decode(code ^ (1u << ambiguous_bit))) : stripe;
  const StripeExtent extent = stripe_extent(stripe, width, a.gray_origin_px);
  const StripeExtent other_extent = stripe_extent(other, width, a.gray_origin_px);
  const bool gray = a.gray_count > 0;
  // No Gray code: a one-period phase cue is its own reference, centred on the axis.
  const float centre = gray ? 0.5f * (extent.lo + extent.hi) : 0.5f * static_cast<float>(a.extent - 1);

  float u = centre;
  float sigma = width * 0.288675135f;  // a uniform stripe: W / sqrt(12)
  for (int g = 0; g < a.phase_group_count; ++g) {
    const WrappedPhase& w = phases[g];
    const float period = a.phase[g].period_px;
    const bool finest = g + 1 == a.phase_group_count;
    // Fringe weaker than its share of the contrast, or noisier than the finest coordinate may
    // be (max_phase_sigma_px) or than the next period can be unwrapped with (a tenth of it).
    const float max_sigma = finest ? t.max_phase_sigma_px : 0.1f * a.phase[g + 1].period_px;
    if (weak_fringe(w, t, contrast, max_sigma)) flags |= kDecodeLowModulation;
    if (g == 0) {
      u = unwrap_coordinate(centre, w.wrapped, period);
      if (gray) {
        // Consistency: the unwrapped coordinate must lie in the decoded stripe, up to the
        // tolerance. Where one bit was ambiguous, its other decision may be the right one.
        // At the edge between two neighbouring stripes (the usual case: the pixel sits on
        // the edge of the bit that changes there) the true coordinate is the candidate
        // nearest that edge: with stripes as wide as the period each stripe holds one
        // candidate, a period apart, so lying in a stripe decides nothing.
        float distance = 0.0f;
        u = unwrap_in_stripe(extent, w.wrapped, period, &distance);
        if (ambiguous == 1) {
          float other_distance = 0.0f;
          const float u_other = unwrap_in_stripe(other_extent, w.wrapped, period, &other_distance);
          const bool above = other == stripe + 1, below = other == stripe - 1;
          if (above || below) {
            const float edge = above ? extent.hi : extent.lo;
            if (std::fabs(u_other - edge) + other_distance < std::fabs(u - edge) + distance) {
              distance = other_distance;
              u = u_other;
            }
          } else if (other_distance < distance) {
            distance = other_distance;
            u = u_other;
          }
        }
        if (distance > t.consistency_tolerance_px) flags |= kDecodeInconsistent;
      }
    } else {
      // A finer period unwrapped by the coarser coordinate; a quarter period off means the
      // coarser one was wrong.
      const float previous = u;
      u = unwrap_coordinate(previous, w.wrapped, period);
      if (std::fabs(u - previous) > 0.25f * period) flags |= kDecodeInconsistent;
    }
    sigma = w.sigma_px;
  }
  if (off_axis(a, t, u)) flags |= kDecodeInconsistent;
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

// Decodes one pixel: references (shadow test), then each coded axis, unwrapped as `Unwrap`
// (DecodeUnwrap: the layout's, fixed at compile time so that a kernel carries one unwrapping's
// code). Triangulation is separate (triangulate_shared.h) and may add kDecodeOutOfRange.
template <int Unwrap, typename Samples>
SLS_HOST_DEVICE inline PixelDecode decode_pixel_unwrapped(const DecodeParams& p, const Samples& samples) {
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
    // Without either, the first phase group's fringe: mean +- B are the brightest and
    // darkest light it saw.
    const AxisCode& a = layout.axes[layout.axes[0].extent > 0 ? 0 : 1];
    if (a.gray_count > 0 && a.gray_inverse_index[a.gray_count - 1] >= 0) {
      const float p0 = samples(a.gray_index[a.gray_count - 1]);
      const float q0 = samples(a.gray_inverse_index[a.gray_count - 1]);
      reference = 0.5f * (p0 + q0);
      contrast = std::fabs(p0 - q0);
      if (!contrast_above_noise(t, p0, q0, contrast)) flags |= kDecodeShadow;
    } else if (a.phase_group_count > 0) {
      const WrappedPhase w = wrapped_phase(a.phase[0], t, samples);
      reference = w.mean;
      contrast = 2.0f * w.modulation;
      if (!contrast_above_noise(t, w.mean + w.modulation, w.mean - w.modulation, contrast)) flags |= kDecodeShadow;
    }
  }
  float worst_sigma = 0.0f;
  if (flags == 0u) {
    for (int axis = 0; axis < 2; ++axis) {
      const AxisCode& a = layout.axes[axis];
      if (a.extent <= 0) continue;
      const AxisDecode d = Unwrap == kUnwrapHeterodyne   ? decode_heterodyne_axis(a, t, samples, contrast)
                           : Unwrap == kUnwrapMicroPhase ? decode_micro_phase_axis(a, t, samples, contrast)
                                                         : decode_axis(a, t, samples, reference, contrast);
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

// The same with the layout's unwrapping chosen per call.
template <typename Samples>
SLS_HOST_DEVICE inline PixelDecode decode_pixel(const DecodeParams& p, const Samples& samples) {
  switch (p.layout.unwrap) {
    case kUnwrapHeterodyne:
      return decode_pixel_unwrapped<kUnwrapHeterodyne>(p, samples);
    case kUnwrapMicroPhase:
      return decode_pixel_unwrapped<kUnwrapMicroPhase>(p, samples);
    default:
      return decode_pixel_unwrapped<kUnwrapGrayPhase>(p, samples);
  }
}

}  // namespace sls

#include "sdk/decode/multi_frequency_shared.h"  // IWYU pragma: export
