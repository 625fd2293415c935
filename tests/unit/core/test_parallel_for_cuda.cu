// parallel_for on a CUDA GPU: the same body as on the CPU gives the same values, loops queued
// on one GpuStream run in order, and a count beyond one block's threads reaches every element.
// The kernel profile (kernel_profile.h) times loops while it is on. Skips with no GPU.
#include <cmath>
#include <cstddef>
#include <vector>

#include <cuda_runtime_api.h>

#include <gtest/gtest.h>

#include "sdk/core/cuda/device_buffer.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/kernel_profile.h"
#include "sdk/core/parallel_for.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

SLS_HOST_DEVICE float element_value(std::size_t i) { return std::sqrt(static_cast<float>(i)) * 0.5f + 1.0f; }

// The loops live in free functions: nvcc refuses a device lambda inside a test's private body.
void fill(const Device& device, float* out, std::size_t count, const GpuStream& stream) {
  parallel_for(device, count, SLS_LAMBDA(std::size_t i) { out[i] = element_value(i); }, stream);
}

void double_values(const Device& device, float* values, std::size_t count, const GpuStream& stream) {
  parallel_for(device, count, SLS_LAMBDA(std::size_t i) { values[i] = 2.0f * values[i]; }, stream);
}

TEST(ParallelForCuda, EqualsTheCpuLoop) {
  SLS_REQUIRE_CUDA_DEVICE();
  const std::size_t count = 3 * kParallelForThreads * 1000 + 17;
  std::vector<float> cpu(count, 0.0f);
  fill(Device::cpu(), cpu.data(), count, GpuStream{});

  const GpuStream stream = GpuStream::create(Device::cuda(0));
  DeviceBuffer<float> values(count);
  fill(Device::cuda(0), values.data(), count, stream);
  // A second loop on the same stream sees the first one's values.
  double_values(Device::cuda(0), values.data(), count, stream);
  std::vector<float> gpu(count, 0.0f);
  values.download(gpu.data(), count, static_cast<cudaStream_t>(stream.native()));
  stream.synchronize();
  for (std::size_t i = 0; i < count; ++i) ASSERT_EQ(gpu[i], 2.0f * cpu[i]) << "element " << i;
}

TEST(ParallelForCuda, StreamsAreSharedAndOwned) {
  SLS_REQUIRE_CUDA_DEVICE();
  const GpuStream stream = GpuStream::create(Device::cuda(0));
  ASSERT_TRUE(stream.valid());
  const GpuStream copy = GpuStream::or_create(stream, Device::cuda(0));
  EXPECT_EQ(copy, stream);  // handed down, not made anew
  EXPECT_NE(GpuStream::or_create(GpuStream{}, Device::cuda(0)), stream);
  EXPECT_FALSE(GpuStream::create(Device::cpu()).valid());
  GpuStream{}.synchronize();  // none: nothing to wait for
}

// A launcher's timer around a loop, as the fusion and decode launchers time theirs.
void timed_fill(float* out, std::size_t count, const GpuStream& stream) {
  const KernelTimer timer("fill", 4.0 * static_cast<double>(count), stream.native());
  fill(Device::cuda(0), out, count, stream);
}

TEST(KernelProfileCuda, TimesEachLaunchWhileOnAndSumsByName) {
  SLS_REQUIRE_CUDA_DEVICE();
  const std::size_t count = std::size_t{1} << 24;
  const GpuStream stream = GpuStream::create(Device::cuda(0));
  DeviceBuffer<float> values(count);
  set_kernel_profiling(false);
  timed_fill(values.data(), count, stream);  // off: not recorded
  set_kernel_profiling(true);
  EXPECT_TRUE(kernel_profiling());
  for (int n = 0; n < 3; ++n) timed_fill(values.data(), count, stream);
  const std::vector<KernelFigures> figures = kernel_profile();
  set_kernel_profiling(false);
  ASSERT_EQ(figures.size(), 1u);
  EXPECT_EQ(figures[0].name, "fill");
  EXPECT_EQ(figures[0].launches, 3u);
  EXPECT_EQ(figures[0].bytes, 3.0 * 4.0 * static_cast<double>(count));
  EXPECT_GT(figures[0].gpu_ms, 0.0);
  EXPECT_GT(figures[0].achieved_gb_s(), 0.0);
  // Turned on again: what was recorded before is gone.
  set_kernel_profiling(true);
  EXPECT_TRUE(kernel_profile().empty());
  set_kernel_profiling(false);
}

// A scan times thousands of launches: those the GPU has finished are summed as it goes (their
// events reused), and none is lost or counted twice, also while an outer timer stays open.
TEST(KernelProfileCuda, SumsFinishedLaunchesAsItGoesWithoutLosingAny) {
  SLS_REQUIRE_CUDA_DEVICE();
  const std::size_t count = std::size_t{1} << 16;
  const GpuStream stream = GpuStream::create(Device::cuda(0));
  DeviceBuffer<float> values(count);
  set_kernel_profiling(true);
  const auto fills = [&](int launches) {
    for (int n = 0; n < launches; ++n) {
      timed_fill(values.data(), count, stream);
      if (n % 50 == 49) stream.synchronize();  // what the frame loop does: the GPU catches up
    }
  };
  fills(700);
  {
    const KernelTimer outer("outer", 1.0, stream.native());  // open while the fills below finish
    fills(300);
  }
  fills(10);
  const std::vector<KernelFigures> figures = kernel_profile();
  set_kernel_profiling(false);
  ASSERT_EQ(figures.size(), 2u);
  const KernelFigures& fill_figures = figures[0].name == "fill" ? figures[0] : figures[1];
  const KernelFigures& outer_figures = figures[0].name == "fill" ? figures[1] : figures[0];
  EXPECT_EQ(fill_figures.name, "fill");
  EXPECT_EQ(fill_figures.launches, 1010u);
  EXPECT_EQ(fill_figures.bytes, 1010.0 * 4.0 * static_cast<double>(count));
  EXPECT_GT(fill_figures.gpu_ms, 0.0);
  EXPECT_EQ(outer_figures.name, "outer");
  EXPECT_EQ(outer_figures.launches, 1u);
  EXPECT_GE(outer_figures.gpu_ms, 0.0);
}

}  // namespace
}  // namespace sls
