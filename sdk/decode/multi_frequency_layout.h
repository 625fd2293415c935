// Internal to sls_decode: the layout checks and fills of the families without a Gray code
// (multi_frequency_shared.h decodes them), for make_decode_layout (decode_layout.cpp).
#pragma once

#include <cstdint>

#include "sdk/decode/decode_shared.h"
#include "sdk/decode/pattern_set.h"

namespace sls::detail {

// A heterodyne axis (its phase groups filled, coarsest first): two or three periods whose
// coarsest beat spans the axis and whose pair beats differ. Throws sls::Error
// (kInvalidArgument) naming the periods and their beats otherwise.
void check_heterodyne_axis(const char* axis_name, const AxisCode& code);

// A micro phase-shifting axis: one period with all its N >= 3 steps (phase[0]) and one image
// of each of 1..kDecodeMaxMicroSingles other periods. Throws sls::Error(kInvalidArgument)
// naming the problem, including frequencies that cannot tell two periods apart
// (micro_phase_code_distance below kMicroMinCodeDistance).
void fill_micro_phase_axis(const PatternSet& set, PatternAxis axis, AxisCode* code);

// The smallest distance between the cosine vectors (cos psi_f of each single image) that two
// different periods of the N-step period predict for one wrapped phase, over the wrapped
// phase: how far apart the search's candidates lie at worst (in cosine units: noise-free, the
// measurement is one of them). `first` and `second` receive such a pair's coordinates.
double micro_phase_code_distance(const AxisCode& code, double* first = nullptr, double* second = nullptr);

// Below this the search cannot tell two periods apart even without noise (a single image's
// period equal to a harmonic of another's, or a band too narrow for the axis).
constexpr double kMicroMinCodeDistance = 0.05;
// The most periods of the N-step period along an axis: each pixel tries every one (4096
// columns at a period of 4 px; DMDs in use have far fewer).
constexpr int kMicroMaxCandidates = 1024;

}  // namespace sls::detail
