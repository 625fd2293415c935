#include "sdk/decode/multi_frequency_layout.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "sdk/core/error.h"

namespace sls::detail {
namespace {

constexpr double kTwoPi = 6.283185307179586476925;

const char* axis_label(PatternAxis axis) { return axis == PatternAxis::kColumns ? "columns" : "rows"; }

std::string periods_text(const float* periods, int count) {
  std::string text;
  for (int i = 0; i < count; ++i) text += fmt::format("{}{:g}", i == 0 ? "" : ", ", periods[i]);
  return text;
}

}  // namespace

void check_heterodyne_axis(const char* axis_name, const AxisCode& code) {
  const int count = code.phase_group_count;
  if (count < 2 || count > 3) {
    throw_error(ErrorCode::kInvalidArgument,
                "a heterodyne set beats two or three phase periods against each other; the {} have {}", axis_name,
                count);
  }
  float periods[kDecodeMaxPhaseGroups];
  for (int i = 0; i < count; ++i) periods[i] = code.phase[count - 1 - i].period_px;  // finest first
  const HeterodyneBeats beats = heterodyne_beats(periods, count);
  if (!std::isfinite(beats.spanning_px)) {
    throw_error(ErrorCode::kInvalidArgument,
                "heterodyne periods {} px on the {}: both pairs beat at {:g} px, so their beats do not beat: choose "
                "periods whose pair beats differ",
                periods_text(periods, count), axis_name, beats.intermediate_px);
  }
  if (!(beats.spanning_px >= static_cast<float>(code.extent))) {
    throw_error(ErrorCode::kInvalidArgument,
                "heterodyne periods {} px on the {}: their {}beat of {:.1f} px is shorter than the {} {} and cannot "
                "number them: choose periods closer together",
                periods_text(periods, count), axis_name, count == 3 ? "pair beats' " : "", beats.spanning_px,
                code.extent, axis_name);
  }
}

double micro_phase_code_distance(const AxisCode& code, double* first, double* second) {
  const double period = code.phase[0].period_px;
  const int singles = code.micro_count;
  const double extent = code.extent;
  const int most_candidates = static_cast<int>(std::ceil(extent / period)) + 1;
  // Wrapped phases sampled finely enough to find the closest approach (it is a smooth
  // function of the phase), fewer on very long axes where the pairs are many.
  const int phases = std::clamp(8192 / std::max(most_candidates, 1), 8, 64);
  double best = INFINITY;
  std::vector<double> codes(static_cast<std::size_t>(most_candidates * singles));
  std::vector<double> coordinates(static_cast<std::size_t>(most_candidates));
  for (int i = 0; i < phases; ++i) {
    const double wrapped = (i + 0.5) / phases * period;
    const double start = wrapped + period * std::ceil((-0.5 - wrapped) / period);
    int candidates = 0;
    for (double u = start; u < extent - 0.5 && candidates < most_candidates; u += period, ++candidates) {
      coordinates[static_cast<std::size_t>(candidates)] = u;
      for (int f = 0; f < singles; ++f) {
        const MicroSingle& s = code.micro[f];
        codes[static_cast<std::size_t>(candidates * singles + f)] =
            std::cos(static_cast<double>(s.sign) * kTwoPi * u / static_cast<double>(s.period_px) +
                     static_cast<double>(s.shift_rad));
      }
    }
    for (int a = 0; a < candidates; ++a) {
      for (int b = a + 1; b < candidates; ++b) {
        double distance = 0.0;
        for (int f = 0; f < singles; ++f) {
          const double d =
              codes[static_cast<std::size_t>(a * singles + f)] - codes[static_cast<std::size_t>(b * singles + f)];
          distance += d * d;
        }
        if (distance < best) {
          best = distance;
          if (first != nullptr) *first = coordinates[static_cast<std::size_t>(a)];
          if (second != nullptr) *second = coordinates[static_cast<std::size_t>(b)];
        }
      }
    }
  }
  return std::sqrt(best);
}

void fill_micro_phase_axis(const PatternSet& set, PatternAxis axis, AxisCode* code) {
  const char* axis_name = axis_label(axis);
  struct PeriodImages {
    double period = 0.0;
    std::vector<std::size_t> patterns;
  };
  std::vector<PeriodImages> periods;
  int extent = 0;
  for (std::size_t k = 0; k < set.patterns.size(); ++k) {
    const PatternDesc& d = set.patterns[k];
    if (d.axis != axis || d.kind == PatternKind::kWhite || d.kind == PatternKind::kBlack) continue;
    if (d.kind != PatternKind::kPhaseShift) {
      throw_error(ErrorCode::kInvalidArgument,
                  "pattern {} ({}): a micro phase-shifting set unwraps by its periods, it has no Gray code", k,
                  pattern_label(d));
    }
    extent = d.extent;
    auto it =
        std::find_if(periods.begin(), periods.end(), [&](const PeriodImages& p) { return p.period == d.period_px; });
    if (it == periods.end()) {
      periods.push_back({d.period_px, {}});
      it = periods.end() - 1;
    }
    it->patterns.push_back(k);
  }
  if (extent == 0) return;
  // One period has its N steps, every other one image.
  const PeriodImages* main = nullptr;
  for (const PeriodImages& p : periods) {
    if (p.patterns.size() < 2) continue;
    if (main != nullptr) {
      throw_error(ErrorCode::kInvalidArgument,
                  "micro phase-shifting set: periods {:g} and {:g} px on the {} both have several images; one period "
                  "takes the N steps and each other period one image",
                  main->period, p.period, axis_name);
    }
    main = &p;
  }
  if (main == nullptr) {
    throw_error(ErrorCode::kInvalidArgument,
                "micro phase-shifting set: no period on the {} has its N >= 3 phase steps (each of the {} periods has "
                "one image)",
                axis_name, periods.size());
  }
  const PatternDesc& first = set.patterns[main->patterns.front()];
  const int steps = first.steps;
  if (steps < 3 || steps > kDecodeMaxPhaseSteps || main->patterns.size() != static_cast<std::size_t>(steps)) {
    throw_error(ErrorCode::kInvalidArgument,
                "micro phase-shifting set: {} images of period {:g} px on the {}, which has {} steps (need all N "
                "steps, N = 3..{})",
                main->patterns.size(), main->period, axis_name, steps, kDecodeMaxPhaseSteps);
  }
  const int singles = static_cast<int>(periods.size()) - 1;
  if (singles < 1 || singles > kDecodeMaxMicroSingles) {
    throw_error(ErrorCode::kInvalidArgument,
                "micro phase-shifting set: {} single-image periods besides the {:g} px one on the {} (need 1..{})",
                singles, main->period, axis_name, kDecodeMaxMicroSingles);
  }
  const double candidates = std::ceil(extent / main->period);
  if (candidates > kMicroMaxCandidates) {
    throw_error(ErrorCode::kInvalidArgument,
                "micro phase-shifting set: {} periods of {:g} px along the {} {}; the search tries at most {} (choose "
                "a longer period)",
                candidates, main->period, extent, axis_name, kMicroMaxCandidates);
  }
  AxisCode out;
  out.extent = extent;
  PhaseGroup& g = out.phase[0];
  g.period_px = static_cast<float>(main->period);
  g.sign = first.phase_reversed ? -1.0f : 1.0f;
  g.offset_rad = static_cast<float>(first.phase_offset_rad);
  std::uint64_t seen_steps = 0;
  for (const std::size_t k : main->patterns) {
    const PatternDesc& d = set.patterns[k];
    if (d.steps != steps || d.phase_reversed != first.phase_reversed || d.phase_offset_rad != first.phase_offset_rad) {
      throw_error(ErrorCode::kInvalidArgument,
                  "pattern {} ({}): phase steps of period {:g} px on the {} with mixed N, sign or offset", k,
                  pattern_label(d), d.period_px, axis_name);
    }
    const std::uint64_t step_bit = std::uint64_t{1} << d.step;
    if ((seen_steps & step_bit) != 0) {
      throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}) repeats a phase step", k, pattern_label(d));
    }
    seen_steps |= step_bit;
    const double angle = kTwoPi * static_cast<double>(d.step) / static_cast<double>(d.steps);
    g.index[g.count] = static_cast<int>(k);
    g.cos_step[g.count] = static_cast<float>(std::cos(angle));
    g.sin_step[g.count] = static_cast<float>(std::sin(angle));
    ++g.count;
  }
  set_phase_group_scales(g);
  out.phase_group_count = 1;
  for (const PeriodImages& p : periods) {
    if (&p == main) continue;
    const PatternDesc& d = set.patterns[p.patterns.front()];
    MicroSingle& s = out.micro[out.micro_count++];
    s.index = static_cast<int>(p.patterns.front());
    s.period_px = static_cast<float>(d.period_px);
    s.sign = d.phase_reversed ? -1.0f : 1.0f;
    s.shift_rad = static_cast<float>(kTwoPi * d.step / d.steps + d.phase_offset_rad);
  }
  double at = 0.0, other = 0.0;
  const double distance = micro_phase_code_distance(out, &at, &other);
  if (!(distance >= kMicroMinCodeDistance)) {
    throw_error(ErrorCode::kInvalidArgument,
                "micro phase-shifting set: the single images on the {} cannot tell the periods of {:g} px apart: at "
                "{:.1f} and {:.1f} px they predict cosines {:.3f} apart (need >= {}); choose other periods",
                axis_name, main->period, at, other, distance, kMicroMinCodeDistance);
  }
  *code = out;
}

}  // namespace sls::detail
