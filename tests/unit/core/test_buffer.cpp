// Memory that knows where it lives: pageable buffers, page-locked ones from the pinned cache
// where a GPU can lock them (else pageable, and saying so), device ones on a GPU (else a clear
// error), deep copies that stay where the source lives, and the cache's reuse and limit.
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/buffer.h"
#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/image.h"
#include "sdk/core/pinned_memory.h"

namespace sls {
namespace {

bool gpu_present() { return cuda_compiled() && cuda_device_count() > 0; }

TEST(Buffer, PageableBufferHoldsItsValuesAndCopiesDeep) {
  Buffer<std::uint16_t> buffer(1000, 7);
  EXPECT_EQ(buffer.size(), 1000u);
  EXPECT_EQ(buffer.memory_type(), MemoryType::kHost);
  EXPECT_FALSE(is_page_locked(buffer.data()));
  buffer[999] = 9;
  Buffer<std::uint16_t> copy = buffer;
  EXPECT_EQ(copy, buffer);
  EXPECT_NE(copy.data(), buffer.data());
  copy[0] = 1;
  EXPECT_EQ(buffer[0], 7);
  Buffer<std::uint16_t> moved = std::move(copy);
  EXPECT_TRUE(copy.empty());  // NOLINT(bugprone-use-after-move): a moved-from buffer is empty
  EXPECT_EQ(moved[0], 1);
  moved.assign(0, 0);
  EXPECT_TRUE(moved.empty());
  EXPECT_EQ(moved.data(), nullptr);
}

TEST(Buffer, PinnedRequestIsPinnedWhereAGpuIsElsePageable) {
  const PinnedMemoryStatistics before = pinned_memory_statistics();
  {
    Buffer<float> buffer(4096, 0.5f, MemoryType::kPinned);
    EXPECT_EQ(buffer.size(), 4096u);
    EXPECT_EQ(buffer[4095], 0.5f);
    if (gpu_present()) {
      EXPECT_EQ(buffer.memory_type(), MemoryType::kPinned);
      EXPECT_TRUE(is_page_locked(buffer.data()));
      EXPECT_EQ(pinned_memory_statistics().in_use_bytes, before.in_use_bytes + 4096 * sizeof(float));
    } else {
      EXPECT_EQ(buffer.memory_type(), MemoryType::kHost);  // said, not pretended
      EXPECT_FALSE(is_page_locked(buffer.data()));
      EXPECT_EQ(pinned_memory_statistics().refusals, before.refusals + 1);
    }
    // A copy lives where its source lives.
    const Buffer<float> copy = buffer;
    EXPECT_EQ(copy.memory_type(), buffer.memory_type());
    EXPECT_EQ(copy, buffer);
  }
  EXPECT_EQ(pinned_memory_statistics().in_use_bytes, before.in_use_bytes);
}

TEST(Buffer, PinnedBlocksAreReusedFromTheCacheWithinItsLimit) {
  if (!gpu_present()) GTEST_SKIP() << "no GPU: nothing is page-locked here";
  trim_pinned_cache();
  const std::size_t count = 3 * 1024 * 1024 + 17;  // a size no other test asks for
  const void* first = nullptr;
  {
    Buffer<std::uint16_t> buffer(count, 1, MemoryType::kPinned);
    first = buffer.data();
  }
  const PinnedMemoryStatistics cached = pinned_memory_statistics();
  EXPECT_EQ(cached.cached_bytes, count * sizeof(std::uint16_t));
  {
    const Buffer<std::uint16_t> again(count, 2, MemoryType::kPinned);
    EXPECT_EQ(again.data(), first);  // the cached block, not a new page-locking
    EXPECT_EQ(again[count - 1], 2);
    EXPECT_EQ(pinned_memory_statistics().reuses, cached.reuses + 1);
    EXPECT_EQ(pinned_memory_statistics().allocations, cached.allocations);
  }
  // Under a lower limit the cache keeps nothing more than it: blocks beyond go back at once.
  set_pinned_cache_limit(1024);
  EXPECT_EQ(pinned_memory_statistics().cached_bytes, 0u);
  { const Buffer<std::uint16_t> more(count, 3, MemoryType::kPinned); }
  EXPECT_EQ(pinned_memory_statistics().cached_bytes, 0u);
  set_pinned_cache_limit(std::uint64_t{4} << 30);
}

TEST(Buffer, DeviceBufferLivesOnTheGpuElseIsAClearError) {
  if (!gpu_present()) {
    // Never a silent fallback to host memory: the GPU stages would read it as device memory.
    EXPECT_THROW(Buffer<float>(16, 1.0f, MemoryType::kDevice), Error);
    return;
  }
  const GpuAllocations before = gpu_allocations();
  {
    Buffer<float> buffer(5000, 2.5f, MemoryType::kDevice);
    EXPECT_EQ(buffer.memory_type(), MemoryType::kDevice);
    EXPECT_FALSE(is_page_locked(buffer.data()));
    EXPECT_EQ(gpu_allocations().in_use_bytes, before.in_use_bytes + 5000 * sizeof(float));
    EXPECT_EQ(buffer.host_values(), std::vector<float>(5000, 2.5f));
    const Buffer<float> copy = buffer;  // deep, on the device
    EXPECT_EQ(copy.memory_type(), MemoryType::kDevice);
    EXPECT_NE(copy.data(), buffer.data());
    EXPECT_EQ(copy, buffer);
    buffer.assign(5000, 0.0f, MemoryType::kDevice);  // same size and place: the same memory, zeroed
    EXPECT_EQ(buffer.host_values(), std::vector<float>(5000, 0.0f));
    EXPECT_FALSE(copy == buffer);
    const Buffer<float> host(5000, 2.5f);
    EXPECT_EQ(host, copy);  // values compared wherever they live
  }
  EXPECT_EQ(gpu_allocations().in_use_bytes, before.in_use_bytes);
}

TEST(Image, DeviceImageCopiesBackToTheSamePixels) {
  if (!gpu_present()) GTEST_SKIP() << "no GPU";
  Image32f host(31, 7, 0.0f);
  for (int y = 0; y < host.height(); ++y) {
    for (int x = 0; x < host.width(); ++x) host(x, y) = static_cast<float>(x * 100 + y);
  }
  Image32f device(MemoryType::kDevice);
  device.resize(31, 7);
  EXPECT_EQ(device.memory_type(), MemoryType::kDevice);
  copy_memory(device.data(), host.data(), host.size_bytes(), true);
  const Image32f copy = device;
  EXPECT_EQ(copy.memory_type(), MemoryType::kDevice);
  EXPECT_EQ(copy, host);
}

// Only the rows asked for are copied, one set after another (every n-th row, as a GPU's map
// comes down for a grid of samples); host to host, and from a GPU when there is one.
TEST(Image, GathersTheRowsAskedForAndNoOther) {
  Image32f source(13, 11, 0.0f);
  for (int y = 0; y < source.height(); ++y) {
    for (int x = 0; x < source.width(); ++x) source(x, y) = static_cast<float>(x * 100 + y);
  }
  const std::vector<RowSet> rows = {{1, 4, 3}, {2, 4, 3}, {10, 1, 1}, {0, 1, 0}};  // rows 1, 5, 9, 2, 6, 10, 10
  const auto check = [&](const Image32f& gathered) {
    const std::vector<int> expected = {1, 5, 9, 2, 6, 10, 10};
    ASSERT_EQ(gathered.width(), source.width());
    ASSERT_EQ(gathered.height(), 7);
    for (int row = 0; row < 7; ++row) {
      for (int x = 0; x < source.width(); ++x) {
        EXPECT_EQ(gathered(x, row), source(x, expected[static_cast<std::size_t>(row)])) << x << ", " << row;
      }
    }
  };
  Image32f gathered(MemoryType::kPinned);
  gathered.gather_rows_from(source, rows);
  check(gathered);
  // Rows outside the image, or a step below 1, are refused before anything is copied.
  EXPECT_THROW(gathered.gather_rows_from(source, {{1, 5, 3}}), Error);
  EXPECT_THROW(gathered.gather_rows_from(source, {{-1, 1, 1}}), Error);
  EXPECT_THROW(gathered.gather_rows_from(source, {{0, 0, 2}}), Error);
  check(gathered);
  Image32f none;
  none.gather_rows_from(source, {});
  EXPECT_EQ(none.height(), 0);
  if (!gpu_present()) return;
  const Image32f device = source.copy_to(MemoryType::kDevice);
  Image32f from_device;
  from_device.gather_rows_from(device, rows);
  check(from_device);
  Image32f pinned_from_device(MemoryType::kPinned);
  pinned_from_device.gather_rows_from(device, rows);
  check(pinned_from_device);
}

TEST(Image, KeepsTheMemoryItWasMadeFor) {
  Image16u plain(8, 4, 3);
  EXPECT_EQ(plain.memory_type(), MemoryType::kHost);
  // A driver makes an empty image for pinned memory and fills it by resize.
  Image16u captured(MemoryType::kPinned);
  captured.resize(64, 32, 5);
  const MemoryType expected = gpu_present() ? MemoryType::kPinned : MemoryType::kHost;
  EXPECT_EQ(captured.memory_type(), expected);
  EXPECT_EQ(captured(63, 31), 5);
  const Image16u copy = captured;
  EXPECT_EQ(copy.memory_type(), expected);
  EXPECT_EQ(copy, captured);
  Image16u resized = copy;
  resized.resize(16, 16, 1);  // still where it was made
  EXPECT_EQ(resized.memory_type(), expected);
  EXPECT_EQ(resized.pixel_count(), 256u);
}

}  // namespace
}  // namespace sls
