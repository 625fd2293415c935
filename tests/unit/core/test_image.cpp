#include <gtest/gtest.h>

#include "sdk/core/error.h"
#include "sdk/core/image.h"

namespace sls {
namespace {

TEST(Image, OwningBufferAndViewAddressTheSamePixels) {
  Image16u image(5, 3, 7);
  EXPECT_EQ(image.pixel_count(), 15u);
  EXPECT_EQ(image.stride_bytes(), 10u);
  image(4, 2) = 65535;
  ImageView<std::uint16_t> view = image.view();
  EXPECT_EQ(view(4, 2), 65535);
  EXPECT_EQ(view(0, 0), 7);
  view(1, 1) = 3;
  EXPECT_EQ(image(1, 1), 3);
  ImageView<const std::uint16_t> const_view = view;
  EXPECT_EQ(const_view(1, 1), 3);
  EXPECT_TRUE(view.contains(4, 2));
  EXPECT_FALSE(view.contains(5, 2));
  EXPECT_FALSE(view.contains(-1, 0));
}

TEST(Image, CopyBetweenViewsWithDifferentStrides) {
  Image32f source(4, 4);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) source(x, y) = static_cast<float>(10 * y + x);
  // A 2x2 window of an 8-wide buffer: stride differs from width.
  Image32f big(8, 2, -1.0f);
  ImageView<float> window{big.data() + 3, 2, 2, big.stride_bytes()};
  ImageView<const float> source_window{source.data() + 4 + 1, 2, 2, source.stride_bytes()};
  copy_pixels(source_window, window);
  EXPECT_EQ(big(3, 0), 11.0f);
  EXPECT_EQ(big(4, 1), 22.0f);
  EXPECT_EQ(big(2, 0), -1.0f);
  EXPECT_THROW(copy_pixels(source.view(), big.view()), Error);
}

TEST(Image, NegativeSizeIsAnError) { EXPECT_THROW(Image8u(-1, 4), Error); }

}  // namespace
}  // namespace sls
