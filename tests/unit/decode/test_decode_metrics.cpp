#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/decode/decode_metrics.h"

namespace sls {
namespace {

TEST(DecodeMetrics, KnownErrorsGiveKnownStatistics) {
  DecodedFrame decoded;
  decoded.projector_u = Image32f(4, 1, 0.0f);
  decoded.depth_m = Image32f(4, 1, 0.1f);
  decoded.mask = Image8u(4, 1, kDecodeOk);
  Image32f true_u(4, 1, 0.0f), true_depth(4, 1, 0.1f);
  Image8u valid(4, 1, 1);
  decoded.projector_u(0, 0) = 0.3f;        // +0.3 px
  decoded.projector_u(1, 0) = -0.4f;       // -0.4 px
  decoded.depth_m(1, 0) = 0.1f + 4e-6f;    // 4 µm
  decoded.mask(2, 0) = kDecodeShadow;      // truly valid, not decoded
  valid(3, 0) = 0;                         // decoded where the truth says shadow
  true_u(3, 0) = std::numeric_limits<float>::quiet_NaN();
  const DecodeErrorStats stats = compare_with_ground_truth(decoded, true_u, true_depth, valid);
  EXPECT_EQ(stats.truth_valid, 3u);
  EXPECT_EQ(stats.compared, 2u);
  EXPECT_EQ(stats.false_valid, 1u);
  EXPECT_NEAR(stats.projector_rms_px(), std::sqrt((0.09 + 0.16) / 2.0), 1e-6);
  EXPECT_NEAR(stats.projector_max_px, 0.4, 1e-6);
  EXPECT_NEAR(stats.depth_rms_um(), std::sqrt(16.0 / 2.0), 0.01);
  EXPECT_NEAR(stats.valid_fraction(), 2.0 / 3.0, 1e-12);
  DecodeErrorStats total;
  total.accumulate(stats);
  total.accumulate(stats);
  EXPECT_NEAR(total.projector_rms_px(), stats.projector_rms_px(), 1e-12);
  EXPECT_EQ(total.compared, 4u);
  EXPECT_THROW(compare_with_ground_truth(decoded, Image32f(3, 1), true_depth, valid), Error);
}

}  // namespace
}  // namespace sls
