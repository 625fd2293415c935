// The transport-independent parts of the Aravis camera driver (drivers/aravis/frame_data.h).
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "drivers/aravis/frame_data.h"
#include "sdk/core/error.h"

namespace sls::drivers {
namespace {

TEST(AravisFrameIds, ConsecutiveIdsMissNothing) {
  EXPECT_EQ(frames_missed_between(7, 8), 0u);
  EXPECT_EQ(frames_missed_between(7, 10), 2u);
  EXPECT_EQ(frames_missed_between(0, 1), 0u);
  EXPECT_EQ(frames_missed_between(65535, 65536), 0u);  // 64-bit ids go on past 16 bits
}

TEST(AravisFrameIds, SixteenBitWrapSkipsZero) {
  // GigE Vision 1.x: 65535 is followed by 1.
  EXPECT_EQ(frames_missed_between(65535, 1), 0u);
  EXPECT_EQ(frames_missed_between(65534, 2), 2u);  // 65535 and 1 were lost
  EXPECT_EQ(frames_missed_between(65000, 5), 539u);
}

TEST(AravisFrameIds, RestartedCounterIsNoGap) {
  EXPECT_EQ(frames_missed_between(100, 5), 0u);         // far from a wrap: the camera restarted
  EXPECT_EQ(frames_missed_between(1000000, 3), 0u);     // a 64-bit counter never wraps
  EXPECT_EQ(frames_missed_between(42, 42), 0u);         // the same frame again
}

TEST(AravisFrameIds, NextIdWrapsLikeTheCamera) {
  EXPECT_EQ(next_frame_id(7), 8u);
  EXPECT_EQ(next_frame_id(65534), 65535u);
  EXPECT_EQ(next_frame_id(65535), 1u);  // GigE Vision 1.x skips 0
  EXPECT_EQ(frames_missed_between(next_frame_id(65535), 2), 0u);
}

TEST(AravisMonoLayouts, KnownAndRefused) {
  ASSERT_NE(find_mono_layout("Mono8"), nullptr);
  EXPECT_EQ(find_mono_layout("Mono8")->bytes_per_pixel, 1);
  EXPECT_EQ(find_mono_layout("Mono12")->bit_depth, 12);
  EXPECT_EQ(find_mono_layout("Mono12")->bytes_per_pixel, 2);
  EXPECT_EQ(find_mono_layout("Mono16")->bit_depth, 16);
  EXPECT_EQ(find_mono_layout("Mono12Packed"), nullptr);
  EXPECT_EQ(find_mono_layout("RGB8"), nullptr);
}

TEST(AravisUnpackMono, Mono8IsStoredAsItIs) {
  const std::vector<std::uint8_t> data = {0, 1, 254, 255, 7, 8};
  Image16u image;
  unpack_mono(data.data(), data.size(), 3, 2, 3, 1, image);
  ASSERT_EQ(image.width(), 3);
  ASSERT_EQ(image.height(), 2);
  EXPECT_EQ(image(0, 0), 0);
  EXPECT_EQ(image(2, 0), 254);  // not scaled to 16 bits
  EXPECT_EQ(image(0, 1), 255);
  EXPECT_EQ(image(2, 1), 8);
}

TEST(AravisUnpackMono, SixteenBitWordsAreLittleEndianAndRowPaddingIsSkipped) {
  // 2x2 pixels, rows of 4 bytes plus 2 bytes of padding.
  const std::vector<std::uint8_t> data = {0x34, 0x12, 0xFF, 0x0F, 0xEE, 0xEE, 0x01, 0x00, 0x00, 0x80};
  Image16u image;
  unpack_mono(data.data(), data.size(), 2, 2, 6, 2, image);
  EXPECT_EQ(image(0, 0), 0x1234);
  EXPECT_EQ(image(1, 0), 0x0FFF);
  EXPECT_EQ(image(0, 1), 0x0001);
  EXPECT_EQ(image(1, 1), 0x8000);
}

TEST(AravisUnpackMono, ShortBufferIsAFormatError) {
  const std::vector<std::uint8_t> data(7, 0);
  Image16u image;
  try {
    unpack_mono(data.data(), data.size(), 2, 2, 4, 2, image);
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kFormat);
  }
  EXPECT_THROW(unpack_mono(data.data(), data.size(), 4, 1, 2, 2, image), Error);  // stride < row
  EXPECT_THROW(unpack_mono(data.data(), data.size(), 0, 1, 2, 2, image), Error);
}

}  // namespace
}  // namespace sls::drivers
