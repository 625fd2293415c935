#include "sdk/decode/decode_metrics.h"

#include <algorithm>
#include <cmath>

#include "sdk/core/error.h"

namespace sls {

double DecodeErrorStats::projector_rms_px() const {
  return compared > 0 ? std::sqrt(projector_sum_squares / static_cast<double>(compared)) : 0.0;
}

double DecodeErrorStats::depth_rms_um() const {
  return compared > 0 ? 1e6 * std::sqrt(depth_sum_squares / static_cast<double>(compared)) : 0.0;
}

double DecodeErrorStats::valid_fraction() const {
  return truth_valid > 0 ? static_cast<double>(compared) / static_cast<double>(truth_valid) : 0.0;
}

void DecodeErrorStats::accumulate(const DecodeErrorStats& other) {
  truth_valid += other.truth_valid;
  compared += other.compared;
  false_valid += other.false_valid;
  projector_sum_squares += other.projector_sum_squares;
  projector_max_px = std::max(projector_max_px, other.projector_max_px);
  depth_sum_squares += other.depth_sum_squares;
  depth_max_m = std::max(depth_max_m, other.depth_max_m);
}

DecodeErrorStats compare_with_ground_truth(const DecodedFrame& decoded, const Image32f& true_projector_u,
                                           const Image32f& true_depth_m, const Image8u& true_valid) {
  const int width = decoded.mask.width(), height = decoded.mask.height();
  for (const auto* image : {&true_projector_u, &true_depth_m}) {
    if (image->width() != width || image->height() != height) {
      throw_error(ErrorCode::kInvalidArgument, "ground truth is {}x{}, the decoded frame {}x{}", image->width(),
                  image->height(), width, height);
    }
  }
  if (true_valid.width() != width || true_valid.height() != height) {
    throw_error(ErrorCode::kInvalidArgument, "ground-truth mask is {}x{}, the decoded frame {}x{}", true_valid.width(),
                true_valid.height(), width, height);
  }
  DecodeErrorStats stats;
  for (std::size_t i = 0; i < decoded.mask.pixel_count(); ++i) {
    const bool ok = decoded.mask.data()[i] == kDecodeOk;
    const bool truth = true_valid.data()[i] != 0;
    if (!truth) {
      stats.false_valid += ok ? 1u : 0u;
      continue;
    }
    ++stats.truth_valid;
    if (!ok) continue;
    ++stats.compared;
    const double u_error =
        std::fabs(static_cast<double>(decoded.projector_u.data()[i]) - static_cast<double>(true_projector_u.data()[i]));
    const double depth_error =
        std::fabs(static_cast<double>(decoded.depth_m.data()[i]) - static_cast<double>(true_depth_m.data()[i]));
    stats.projector_sum_squares += u_error * u_error;
    stats.projector_max_px = std::max(stats.projector_max_px, u_error);
    stats.depth_sum_squares += depth_error * depth_error;
    stats.depth_max_m = std::max(stats.depth_max_m, depth_error);
  }
  return stats;
}

}  // namespace sls
