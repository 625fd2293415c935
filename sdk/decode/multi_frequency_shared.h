// Per-pixel unwrapping of the axes that have no Gray code, shared by the CPU and CUDA decoders
// (DESIGN.md section 6): multi-frequency heterodyne and micro phase shifting. decode_pixel
// (decode_shared.h) calls them for sets of those kinds; quality flags and the predicted noise
// that the confidence comes from mean what they mean for the other families.
//
// Heterodyne (temporal phase unwrapping by beats): N-step phase shifts at two or three periods
// P0 < P1 < P2. Two periods beat at P01 = P0 P1 / (P1 - P0): frac(u/P0 - u/P1) = frac(u/P01),
// so the difference of their wrapped phases is the phase of a fringe of period P01. With three,
// the pair beats P01 and P12 beat again at P012 = P01 P12 / |P12 - P01| (the classic
// 70/64/59 periods across a width: beats of 6 and 5, and 1). The coarsest beat must span the
// axis (the layout refuses a set whose does not); it is unwrapped about the axis' centre, both
// pair beats from it, then each real period from their best linear combination (the two share
// the middle period's error with opposite signs, so it partly cancels: 1.8x less noise than
// the finer pair beat alone for the classic periods), and the coordinate is the
// inverse-variance mean of the real periods' (their noise is what the confidence sees). The
// beats' noise is the real phases' amplified by P_beat / P: each level must be precise enough
// to unwrap the next (a tenth of its period, as for multi-period Gray/phase sets), and a level
// a quarter period off the one above, or a real period off the mean by more than the
// consistency tolerance, leaves the pixel inconsistent rather than moved by a period.
//
// Micro phase shifting (Gupta & Nayar, CVPR 2012): an N-step phase shift of one period P and
// one image each of F - 1 nearby periods P_f, all in a narrow band so that defocus and global
// light attenuate them alike: one offset O and amplitude A for every image. The linear system
// I = M (O, A cos phi, A sin phi, A cos psi_1, ..., A cos psi_{F-1}) is block-triangular: the
// N steps give O, A and phi (the ordinary N-step estimate), each single image cos psi_f =
// (I_f - O) / A. Unwrapping searches the periods of P: each candidate u_n = w + n P along the
// axis predicts cos psi_f(u_n), and the candidate nearest the measured vector (in units of the
// measurement noise) wins. A decision within gray_margin_sigma of the halfway point to the next
// nearest candidate is flagged low-modulation (the noise could have made it), a measurement
// farther from the winner than halfway to that next one inconsistent (no candidate explains
// it: mixed light at a crease). The coordinate is the N-step period's alone: the single images
// carry the band's small amplitude differences (the blur's MTF varies across it), which would
// bias it.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "sdk/core/host_device.h"
#include "sdk/decode/decode_shared.h"

// Loops over a fixed bound with the count as a guard, fully unrolled on the GPU, so that the
// per-period arrays below stay in registers (a runtime bound would put them in local memory).
// SLS_UNROLL_BY(n): a partial unroll, on the GPU only.
#if defined(__CUDA_ARCH__)
#define SLS_UNROLL_FULLY _Pragma("unroll")
#define SLS_PRAGMA(x) _Pragma(#x)
#define SLS_UNROLL_BY(n) SLS_PRAGMA(unroll n)
#else
#define SLS_UNROLL_FULLY
#define SLS_UNROLL_BY(n)
#endif

namespace sls {

// The beat of periods pa < pb.
SLS_HOST_DEVICE inline float beat_period(float pa, float pb) { return pa * pb / (pb - pa); }

// The beat's wrapped coordinate in [0, P_ab) from the two wrapped coordinates (pa < pb).
SLS_HOST_DEVICE inline float beat_wrapped(float wa, float pa, float wb, float pb, float pab) {
  float turns = wa / pa - wb / pb;
  turns -= std::floor(turns);
  const float w = turns * pab;
  return w >= pab ? w - pab : w;
}

// The unwrapping levels of a heterodyne axis from its periods, finest first.
struct HeterodyneBeats {
  float spanning_px = 0.0f;      // the coarsest beat: must reach across the axis
  float intermediate_px = 0.0f;  // three periods: the finer pair beat; 0 with two
  int intermediate_pair = 0;     // its pair: 0 = (P0, P1), 1 = (P1, P2)
};

SLS_HOST_DEVICE inline HeterodyneBeats heterodyne_beats(const float* periods_finest_first, int count) {
  HeterodyneBeats b;
  const float* p = periods_finest_first;
  if (count == 2) {
    b.spanning_px = beat_period(p[0], p[1]);
    return b;
  }
  const float p01 = beat_period(p[0], p[1]);
  const float p12 = beat_period(p[1], p[2]);
  b.intermediate_pair = p01 <= p12 ? 0 : 1;
  b.intermediate_px = p01 <= p12 ? p01 : p12;
  const float other = p01 <= p12 ? p12 : p01;
  b.spanning_px = other > b.intermediate_px ? beat_period(b.intermediate_px, other) : INFINITY;
  return b;
}

template <typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_heterodyne_axis(const AxisCode& a, const DecodeThresholds& t,
                                                         const Samples& samples, float contrast) {
  AxisDecode out{NAN, 0.0f, 0u};
  std::uint8_t flags = 0u;
  const int count = a.phase_group_count;  // 2 or 3 (the layout's check)
  WrappedPhase w[kDecodeMaxPhaseGroups] = {};  // zeroed: at -O1 GCC cannot see the loop sets w[0] (count >= 2)
  float period[kDecodeMaxPhaseGroups] = {};
  float turn_variance[kDecodeMaxPhaseGroups] = {};  // (sigma / P)^2: the phase noise in turns
  SLS_UNROLL_FULLY
  for (int i = 0; i < kDecodeMaxPhaseGroups; ++i) {
    if (i >= count) break;
    const PhaseGroup& g = a.phase[count - 1 - i];  // the layout holds them coarsest first
    w[i] = wrapped_phase(g, t, samples);
    period[i] = g.period_px;
    if (w[i].saturated) flags |= kDecodeSaturated;
    // Each period's own fringe against the contrast; its noise is judged in the mean below.
    if (weak_fringe(w[i], t, contrast, INFINITY)) flags |= kDecodeLowModulation;
    const float turns = w[i].sigma_px / period[i];
    turn_variance[i] = turns * turns;
  }
  out.sigma_px = w[0].sigma_px;
  if (flags != 0u) {
    out.flags = flags;
    return out;
  }
  const HeterodyneBeats beats = heterodyne_beats(period, count);
  // The real periods are unwrapped from `reference`, good to a tenth of the finest of them.
  float reference = 0.0f;
  const float centre = 0.5f * static_cast<float>(a.extent - 1);
  if (count == 2) {
    const float span = beat_wrapped(w[0].wrapped, period[0], w[1].wrapped, period[1], beats.spanning_px);
    const float sigma = beats.spanning_px * std::sqrt(turn_variance[0] + turn_variance[1]);
    if (!(sigma <= 0.1f * period[0])) flags |= kDecodeLowModulation;
    reference = unwrap_coordinate(centre, span, beats.spanning_px);
  } else {
    const float p01 = beat_period(period[0], period[1]);
    const float p12 = beat_period(period[1], period[2]);
    const float w01 = beat_wrapped(w[0].wrapped, period[0], w[1].wrapped, period[1], p01);
    const float w12 = beat_wrapped(w[1].wrapped, period[1], w[2].wrapped, period[2], p12);
    const bool pair0 = beats.intermediate_pair == 0;
    const float span = pair0 ? beat_wrapped(w01, p01, w12, p12, beats.spanning_px)
                             : beat_wrapped(w12, p12, w01, p01, beats.spanning_px);
    // u / P012 = +-(u/P0 - 2 u/P1 + u/P2): the middle period's noise counts twice.
    const float span_sigma =
        beats.spanning_px * std::sqrt(turn_variance[0] + 4.0f * turn_variance[1] + turn_variance[2]);
    const float coarse = unwrap_coordinate(centre, span, beats.spanning_px);
    const float u01 = unwrap_coordinate(coarse, w01, p01);
    const float u12 = unwrap_coordinate(coarse, w12, p12);
    if (std::fabs(u01 - coarse) > 0.25f * p01 || std::fabs(u12 - coarse) > 0.25f * p12) {
      flags |= kDecodeInconsistent;
    }
    // Their best linear unbiased combination: errors p01 (e0 - e1) and p12 (e1 - e2) in turns,
    // covariant through e1.
    const float var01 = p01 * p01 * (turn_variance[0] + turn_variance[1]);
    const float var12 = p12 * p12 * (turn_variance[1] + turn_variance[2]);
    const float covariance = -p01 * p12 * turn_variance[1];
    const float spread = var01 + var12 - 2.0f * covariance;
    const float weight01 = (var12 - covariance) / spread;
    reference = weight01 * u01 + (1.0f - weight01) * u12;
    const float reference_sigma = std::sqrt((var01 * var12 - covariance * covariance) / spread);
    if (!(span_sigma <= 0.1f * beats.intermediate_px) || !(reference_sigma <= 0.1f * period[0])) {
      flags |= kDecodeLowModulation;
    }
  }
  // Each real period from the reference, then their inverse-variance mean.
  float u[kDecodeMaxPhaseGroups];
  float weight_sum = 0.0f, weighted = 0.0f;
  SLS_UNROLL_FULLY
  for (int i = 0; i < kDecodeMaxPhaseGroups; ++i) {
    if (i >= count) break;
    u[i] = unwrap_coordinate(reference, w[i].wrapped, period[i]);
    if (std::fabs(u[i] - reference) > 0.25f * period[i]) flags |= kDecodeInconsistent;
    const float weight = 1.0f / (w[i].sigma_px * w[i].sigma_px);
    weight_sum += weight;
    weighted += weight * u[i];
  }
  const float mean = weighted / weight_sum;
  SLS_UNROLL_FULLY
  for (int i = 0; i < kDecodeMaxPhaseGroups; ++i) {
    if (i >= count) break;
    if (std::fabs(u[i] - mean) > t.consistency_tolerance_px) flags |= kDecodeInconsistent;
  }
  const float sigma = 1.0f / std::sqrt(weight_sum);
  if (!(sigma <= t.max_phase_sigma_px)) flags |= kDecodeLowModulation;
  if (off_axis(a, t, mean)) flags |= kDecodeInconsistent;
  out.flags = flags;
  out.sigma_px = sigma;
  if (flags == 0u) out.coordinate = mean;
  return out;
}

// sin(pi x) and cos(pi x): angles in half turns, so that the GPU's range reduction is exact and
// short (sincospif; sincosf carries a long path for huge arguments in every inlined copy).
SLS_HOST_DEVICE inline void sin_cos_pi(float x, float* s, float* c) {
#if defined(__CUDA_ARCH__)
  sincospif(x, s, c);
#else
  const float angle = 3.14159265358979324f * x;
  *s = std::sin(angle);
  *c = std::cos(angle);
#endif
}

SLS_HOST_DEVICE inline float cos_pi(float x) {
#if defined(__CUDA_ARCH__)
  return cospif(x);
#else
  return std::cos(3.14159265358979324f * x);
#endif
}

// The phase a micro phase-shifting single image shows at coordinate u, in half turns (the
// angle / pi), reduced in turns first so that a long axis loses no precision.
SLS_HOST_DEVICE inline float micro_single_half_turns(const MicroSingle& single, float u) {
  float turns = u / single.period_px;
  turns -= std::floor(turns);
  return single.sign * 2.0f * turns + single.shift_rad * 0.318309886183790672f;
}

// The candidate search re-evaluates its cosines this often, so that float rounding cannot
// accumulate along a long axis.
constexpr int kMicroReseedCandidates = 32;

namespace detail {

// decode_micro_phase_axis past the N-step phase m, for `Singles` single images: a compile-time
// count, so that the per-image arrays are registers sized for this set (a kernel sized for the
// most images would hold them all) and the loops over them carry no guard.
template <int Singles, typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_micro_singles(const AxisCode& a, const DecodeThresholds& t,
                                                       const Samples& samples, const WrappedPhase& m) {
  constexpr std::size_t kSize = Singles > 0 ? static_cast<std::size_t>(Singles) : 1u;
  AxisDecode out{NAN, m.sigma_px, 0u};
  std::uint8_t flags = 0u;
  const PhaseGroup& g = a.phase[0];
  // The rest of the linear system: cos psi_f = (I_f - O) / A, and its noise (I_f's and O's;
  // A's scales every component alike and moves no decision). Kept in noise units:
  // weighted = cos psi_f / sigma_f.
  float weighted[kSize] = {}, inverse_sigma[kSize] = {};
  const float inverse_amplitude = 1.0f / m.modulation;
  const float offset_variance = sample_variance(t, m.mean) / static_cast<float>(g.count);
  SLS_UNROLL_FULLY
  for (int f = 0; f < Singles; ++f) {
    const float value = samples(a.micro[f].index);
    if (value >= t.saturation_dn) flags |= kDecodeSaturated;
    inverse_sigma[f] = m.modulation / std::sqrt(sample_variance(t, value) + offset_variance);
    weighted[f] = (value - m.mean) * inverse_amplitude * inverse_sigma[f];
  }
  if (flags != 0u) {
    out.flags = flags;
    return out;
  }
  // Candidates u_n = w + n P over [-0.5, extent - 0.5); each single's predicted cosine turns by
  // a fixed angle t_f from one to the next, so the search costs no cosine per candidate: the
  // Chebyshev recurrence cos(a + t) = 2 cos t cos a - cos(a - t) steps it with one
  // multiply-add. Distances are in units of the noise.
  const float period = g.period_px;
  const float first_u = m.wrapped + period * std::ceil((-0.5f - m.wrapped) / period);
  const int candidates = static_cast<int>(std::ceil((static_cast<float>(a.extent) - 0.5f - first_u) / period));
  float twice_cos_turn[kSize] = {}, sin_turn[kSize] = {};
  SLS_UNROLL_FULLY
  for (int f = 0; f < Singles; ++f) {
    float cos_turn = 0.0f;
    sin_cos_pi(a.micro[f].sign * 2.0f * (period / a.micro[f].period_px), &sin_turn[f], &cos_turn);
    twice_cos_turn[f] = 2.0f * cos_turn;
  }
  float c[kSize] = {}, previous[kSize] = {};  // the predictions at candidate n and n - 1
  float best = INFINITY, second = INFINITY;
  int best_n = 0, second_n = 0;
  for (int begin = 0; begin < candidates; begin += kMicroReseedCandidates) {
    // Reseed: the cosine at candidate `begin`, and cos(a - t) = cos a cos t + sin a sin t.
    const float u_begin = first_u + static_cast<float>(begin) * period;
    SLS_UNROLL_FULLY
    for (int f = 0; f < Singles; ++f) {
      float s_f = 0.0f;
      sin_cos_pi(micro_single_half_turns(a.micro[f], u_begin), &s_f, &c[f]);
      previous[f] = c[f] * (0.5f * twice_cos_turn[f]) + s_f * sin_turn[f];
    }
    const int end = candidates - begin > kMicroReseedCandidates ? begin + kMicroReseedCandidates : candidates;
    // By two on the GPU, so that c and previous swap roles rather than being copied.
    SLS_UNROLL_BY(2)
    for (int n = begin; n < end; ++n) {
      float cost = 0.0f;
      SLS_UNROLL_FULLY
      for (int f = 0; f < Singles; ++f) {
        const float d = weighted[f] - inverse_sigma[f] * c[f];
        cost += d * d;
        const float next = twice_cos_turn[f] * c[f] - previous[f];
        previous[f] = c[f];
        c[f] = next;
      }
      // The two nearest so far, as selects (a branch here costs the GPU more than the search).
      const bool nearest = cost < best;
      const bool runner_up = cost < second;
      second_n = nearest ? best_n : (runner_up ? n : second_n);
      second = nearest ? best : (runner_up ? cost : second);
      best_n = nearest ? n : best_n;
      best = nearest ? cost : best;
    }
  }
  const float u = first_u + static_cast<float>(best_n) * period;
  if (candidates >= 2) {
    // The two nearest candidates' separation, and how far the measurement lies from the
    // plane halfway between them (both in noise sigmas).
    const float u_second = first_u + static_cast<float>(second_n) * period;
    float separation = 0.0f;
    SLS_UNROLL_FULLY
    for (int f = 0; f < Singles; ++f) {
      const float d = (cos_pi(micro_single_half_turns(a.micro[f], u)) -
                       cos_pi(micro_single_half_turns(a.micro[f], u_second))) * inverse_sigma[f];
      separation += d * d;
    }
    separation = std::sqrt(separation);
    const float margin = (second - best) / (2.0f * separation);
    if (!(margin > t.gray_margin_sigma)) flags |= kDecodeLowModulation;
    if (!(std::sqrt(best) < 0.5f * separation)) flags |= kDecodeInconsistent;
  }
  if (off_axis(a, t, u)) flags |= kDecodeInconsistent;
  out.flags = flags;
  if (flags == 0u) out.coordinate = u;
  return out;
}

// decode_micro_singles for the runtime count `singles` (the layout's 1..kDecodeMaxMicroSingles).
template <int Max, typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_micro_singles_of(int singles, const AxisCode& a, const DecodeThresholds& t,
                                                          const Samples& samples, const WrappedPhase& m) {
  if constexpr (Max > 0) {
    if (singles < Max) return decode_micro_singles_of<Max - 1>(singles, a, t, samples, m);
  }
  return decode_micro_singles<Max>(a, t, samples, m);
}

}  // namespace detail

template <typename Samples>
SLS_HOST_DEVICE inline AxisDecode decode_micro_phase_axis(const AxisCode& a, const DecodeThresholds& t,
                                                          const Samples& samples, float contrast) {
  AxisDecode out{NAN, 0.0f, 0u};
  std::uint8_t flags = 0u;
  const WrappedPhase m = wrapped_phase(a.phase[0], t, samples);
  out.sigma_px = m.sigma_px;
  if (m.saturated) flags |= kDecodeSaturated;
  if (weak_fringe(m, t, contrast, t.max_phase_sigma_px) || !(m.modulation > 0.0f)) flags |= kDecodeLowModulation;
  if (flags != 0u) {
    out.flags = flags;
    return out;
  }
  return detail::decode_micro_singles_of<kDecodeMaxMicroSingles>(a.micro_count, a, t, samples, m);
}

}  // namespace sls
