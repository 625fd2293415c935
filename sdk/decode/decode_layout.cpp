// make_decode_layout (decoder.h): where each pattern of a set sits in the stack, per axis, for
// every family (pattern_set.h; heterodyne and micro phase shifting's own checks in
// multi_frequency_layout.cpp), and the checks that the set can be decoded at all.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "sdk/core/error.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/multi_frequency_layout.h"

namespace sls {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct GroupKey {
  double period = 0.0;
  int steps = 0;
  bool reversed = false;
  double offset = 0.0;
  bool operator==(const GroupKey& o) const {
    return period == o.period && steps == o.steps && reversed == o.reversed && offset == o.offset;
  }
};

struct GroupBuild {
  GroupKey key;
  PhaseGroup group;
  std::uint64_t seen_steps = 0;  // bit k: step k given (a mask: kDecodeMaxPhaseSteps is small)
};

// Fills one axis of the layout from the set's patterns along it (every kind but micro phase
// shifting, whose single images are no phase groups: multi_frequency_layout.cpp).
void fill_axis(const PatternSet& set, PatternAxis axis, AxisCode* code) {
  const bool heterodyne = set.kind == PatternSetKind::kHeterodyne;
  const char* axis_name = axis == PatternAxis::kColumns ? "columns" : "rows";
  int normal_index[32];
  int inverse_index[32];
  std::fill(normal_index, normal_index + 32, -1);
  std::fill(inverse_index, inverse_index + 32, -1);
  int extent = 0;
  const PatternDesc* first_gray = nullptr;
  std::vector<GroupBuild> groups;
  for (std::size_t k = 0; k < set.patterns.size(); ++k) {
    const PatternDesc& d = set.patterns[k];
    if (d.axis != axis || (d.kind != PatternKind::kGrayCode && d.kind != PatternKind::kPhaseShift)) continue;
    extent = d.extent;
    const int index = static_cast<int>(k);
    if (d.kind == PatternKind::kGrayCode) {
      if (heterodyne) {
        throw_error(ErrorCode::kInvalidArgument,
                    "pattern {} ({}): a heterodyne set unwraps by the beats of its periods, it has no Gray code", k,
                    pattern_label(d));
      }
      if (d.bit < 0 || d.bit >= 32) {
        throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}): Gray bit {} out of range", k, pattern_label(d),
                    d.bit);
      }
      if (first_gray == nullptr) first_gray = &d;
      if (d.gray_unit_px != first_gray->gray_unit_px || d.gray_origin_px != first_gray->gray_origin_px) {
        throw_error(ErrorCode::kInvalidArgument,
                    "pattern {} ({}): Gray stripes of unit {} px from {} px, the {}' other Gray patterns {} px from "
                    "{} px: one code per axis",
                    k, pattern_label(d), d.gray_unit_px, d.gray_origin_px, axis_name, first_gray->gray_unit_px,
                    first_gray->gray_origin_px);
      }
      int* slot = d.inverted ? &inverse_index[d.bit] : &normal_index[d.bit];
      if (*slot >= 0) {
        throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}) repeats pattern {}", k, pattern_label(d), *slot);
      }
      *slot = index;
      continue;
    }
    const GroupKey key{d.period_px, d.steps, d.phase_reversed, d.phase_offset_rad};
    auto it = std::find_if(groups.begin(), groups.end(), [&](const GroupBuild& g) { return g.key == key; });
    if (it == groups.end()) {
      for (const GroupBuild& g : groups) {
        if (g.key.period == key.period) {
          throw_error(ErrorCode::kInvalidArgument,
                      "pattern {} ({}): phase steps of period {} px on the {} with mixed N, sign or offset", k,
                      pattern_label(d), d.period_px, axis_name);
        }
      }
      if (groups.size() >= static_cast<std::size_t>(kDecodeMaxPhaseGroups)) {
        throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}): more than {} phase periods on the {}", k,
                    pattern_label(d), kDecodeMaxPhaseGroups, axis_name);
      }
      if (d.steps > kDecodeMaxPhaseSteps) {
        throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}): more than {} phase steps", k, pattern_label(d),
                    kDecodeMaxPhaseSteps);
      }
      GroupBuild build;
      build.key = key;
      build.group.period_px = static_cast<float>(d.period_px);
      build.group.sign = d.phase_reversed ? -1.0f : 1.0f;
      build.group.offset_rad = static_cast<float>(d.phase_offset_rad);
      groups.push_back(build);
      it = groups.end() - 1;
    }
    if (d.step < 0 || d.step >= d.steps) {
      throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}): phase step {} of {}", k, pattern_label(d), d.step,
                  d.steps);
    }
    const std::uint64_t step_bit = std::uint64_t{1} << d.step;
    if ((it->seen_steps & step_bit) != 0) {
      throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}) repeats a phase step", k, pattern_label(d));
    }
    it->seen_steps |= step_bit;
    PhaseGroup& g = it->group;
    const double angle = 2.0 * kPi * static_cast<double>(d.step) / static_cast<double>(d.steps);
    g.index[g.count] = index;
    g.cos_step[g.count] = static_cast<float>(std::cos(angle));
    g.sin_step[g.count] = static_cast<float>(std::sin(angle));
    ++g.count;
  }
  if (extent == 0) return;
  // Gray bits: a contiguous run lowest..highest whose highest bit numbers the whole axis.
  int lowest = -1, highest = -1;
  for (int bit = 0; bit < 32; ++bit) {
    if (normal_index[bit] < 0) {
      if (inverse_index[bit] >= 0) {
        throw_error(ErrorCode::kInvalidArgument, "inverse Gray bit {} on the {} without its pattern", bit,
                    axis_name);
      }
      continue;
    }
    if (lowest < 0) lowest = bit;
    if (highest >= 0 && highest != bit - 1) {
      throw_error(ErrorCode::kInvalidArgument, "Gray bits on the {} skip bit {}: bits must be contiguous",
                  axis_name, highest + 1);
    }
    highest = bit;
  }
  const int gray_count = lowest < 0 ? 0 : highest - lowest + 1;
  if (gray_count > kDecodeMaxGrayBits) {
    throw_error(ErrorCode::kInvalidArgument, "{} Gray bits on the {}: at most {}", gray_count, axis_name,
                kDecodeMaxGrayBits);
  }
  const double unit = first_gray != nullptr && first_gray->gray_unit_px > 0.0 ? first_gray->gray_unit_px : 1.0;
  if (gray_count > 0 && highest + 1 < gray_code_bits(*first_gray)) {
    throw_error(ErrorCode::kInvalidArgument,
                "Gray bits {}..{} on the {} number only {} of the {} stripes: the coarsest bit is missing", highest,
                lowest, axis_name, std::int64_t{1} << (highest + 1), std::int64_t{1} << gray_code_bits(*first_gray));
  }
  for (GroupBuild& g : groups) {
    if (g.group.count != g.key.steps || g.key.steps < 3) {
      throw_error(ErrorCode::kInvalidArgument, "{} of {} phase steps of period {} px on the {} (need all N >= 3)",
                  g.group.count, g.key.steps, g.key.period, axis_name);
    }
  }
  // Coarse to fine: each period is unwrapped by the coordinate of the one before.
  std::sort(groups.begin(), groups.end(),
            [](const GroupBuild& a, const GroupBuild& b) { return a.key.period > b.key.period; });
  if (heterodyne) {
    // The beats number the periods (multi_frequency_layout.cpp checks that they can).
  } else if (!groups.empty()) {
    const double period = groups.front().key.period;
    const double width = unit * std::ldexp(1.0, lowest < 0 ? 0 : lowest);
    if (gray_count == 0) {
      if (extent > period) {
        throw_error(ErrorCode::kInvalidArgument,
                    "phase on the {} has {} periods and no Gray code to number them (a set whose periods' beats "
                    "number them is of kind \"heterodyne\")",
                    axis_name, std::ceil(extent / period));
      }
    } else if (width > period) {
      // The rounding in unwrap_coordinate needs the stripe centre within P/2 of u; stripes up
      // to a period wide are tie-broken by the phase (decode_shared.h).
      throw_error(ErrorCode::kInvalidArgument,
                  "finest Gray bit {} on the {} gives stripes of {} px, wider than the phase period {}: add the "
                  "next finer bit",
                  lowest, axis_name, width, period);
    }
  } else if (gray_count == 0) {
    throw_error(ErrorCode::kInvalidArgument, "the {} have neither Gray code nor phase", axis_name);
  }
  code->extent = extent;
  code->gray_count = gray_count;
  code->gray_lowest_bit = lowest < 0 ? 0 : lowest;
  code->gray_unit_px = static_cast<float>(unit);
  code->gray_origin_px = first_gray != nullptr ? static_cast<float>(first_gray->gray_origin_px) : 0.0f;
  for (int i = 0; i < gray_count; ++i) {
    code->gray_index[i] = normal_index[lowest + i];
    code->gray_inverse_index[i] = inverse_index[lowest + i];
  }
  code->phase_group_count = static_cast<int>(groups.size());
  for (std::size_t g = 0; g < groups.size(); ++g) {
    code->phase[g] = groups[g].group;
    set_phase_group_scales(code->phase[g]);
  }
  if (heterodyne) detail::check_heterodyne_axis(axis_name, *code);
}

}  // namespace

DecodeLayout make_decode_layout(const PatternSet& set) {
  validate_pattern_set(set);
  DecodeLayout layout;
  layout.unwrap = set.kind == PatternSetKind::kHeterodyne   ? kUnwrapHeterodyne
                  : set.kind == PatternSetKind::kMicroPhase ? kUnwrapMicroPhase
                                                            : kUnwrapGrayPhase;
  layout.pattern_count = static_cast<int>(set.size());
  for (std::size_t k = 0; k < set.patterns.size(); ++k) {
    const PatternDesc& d = set.patterns[k];
    int* slot = d.kind == PatternKind::kWhite ? &layout.white_index
                : d.kind == PatternKind::kBlack ? &layout.black_index
                                                : nullptr;
    if (slot == nullptr) continue;
    if (*slot >= 0) {
      throw_error(ErrorCode::kInvalidArgument, "pattern {} ({}) repeats pattern {}", k, pattern_label(d), *slot);
    }
    *slot = static_cast<int>(k);
  }
  const auto fill = set.kind == PatternSetKind::kMicroPhase ? detail::fill_micro_phase_axis : fill_axis;
  fill(set, PatternAxis::kColumns, &layout.axes[0]);
  fill(set, PatternAxis::kRows, &layout.axes[1]);
  if (layout.axes[0].extent <= 0 && layout.axes[1].extent <= 0) {
    throw_error(ErrorCode::kInvalidArgument, "pattern set '{}' codes neither columns nor rows", set.name);
  }
  const bool references = layout.white_index >= 0 && layout.black_index >= 0;
  if (set.gray_threshold == GrayThresholdMode::kWhiteBlack && !references) {
    throw_error(ErrorCode::kInvalidArgument,
                "pattern set '{}' thresholds Gray patterns against white and black but has not both", set.name);
  }
  for (AxisCode& axis : layout.axes) {
    if (axis.extent <= 0) continue;
    bool all_complements = true;
    for (int i = 0; i < axis.gray_count; ++i) all_complements = all_complements && axis.gray_inverse_index[i] >= 0;
    const bool phase_mean = set.gray_threshold == GrayThresholdMode::kPhaseMean ||
                            (set.gray_threshold == GrayThresholdMode::kAuto && !references);
    if (phase_mean && axis.gray_count > 0 && !all_complements) {
      if (axis.phase_group_count == 0) {
        throw_error(ErrorCode::kInvalidArgument,
                    "pattern set '{}' has Gray patterns without inverses and neither white and black references "
                    "nor phase images: no threshold to decode against",
                    set.name);
      }
      axis.gray_threshold = kGrayThresholdPhaseMean;
    }
  }
  // Without references the shadow test needs a complementary pair or a phase group on the
  // first coded axis (decode_pixel).
  const AxisCode& first = layout.axes[layout.axes[0].extent > 0 ? 0 : 1];
  const bool pair = first.gray_count > 0 && first.gray_inverse_index[first.gray_count - 1] >= 0;
  if (!references && !pair && first.phase_group_count == 0) {
    throw_error(ErrorCode::kInvalidArgument,
                "pattern set '{}' has neither white and black references nor inverse Gray patterns nor phase: no "
                "threshold to decode against",
                set.name);
  }
  return layout;
}

}  // namespace sls
