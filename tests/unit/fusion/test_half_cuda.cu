// The compact format's conversions on the GPU against their definition (volume_shared.h: the
// hardware's float <-> binary16 conversions there, the integer definition on the CPU): every
// one of the 2^32 floats and the 2^16 halves, bit for bit, NaNs included. Skips with no GPU.
#include <cstdint>

#include <cuda_runtime_api.h>

#include <gtest/gtest.h>

#include "fusion/volume_shared.h"
#include "sdk/core/cuda/device_buffer.h"
#include "sdk/core/gpu_stream.h"
#include "tests/support/test_support.h"

namespace sls::fusion {
namespace {

struct Mismatches {
  unsigned long long count = 0;
  std::uint32_t lowest = 0xffffffffu;  // the lowest input (its bits) that differs
};

// Kernels of their own (not parallel_for): the counting is device code only.
__global__ void compare_floats_kernel(std::uint64_t first, std::uint64_t count, Mismatches* out) {
  const std::uint64_t i = static_cast<std::uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  if (i >= count) return;
  const auto bits = static_cast<std::uint32_t>(first + i);
  const float value = bits_float(bits);
  if (float_to_half(value) != float_to_half_bits(value)) {
    atomicAdd(&out->count, 1ull);
    atomicMin(&out->lowest, bits);
  }
}

__global__ void compare_halves_kernel(Mismatches* out) {
  const unsigned i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= (1u << 16)) return;
  const auto half = static_cast<std::uint16_t>(i);
  if (float_bits(half_to_float(half)) != float_bits(half_to_float_bits(half))) {
    atomicAdd(&out->count, 1ull);
    atomicMin(&out->lowest, static_cast<std::uint32_t>(half));
  }
}

Mismatches run(const GpuStream& stream, bool floats) {
  DeviceBuffer<Mismatches> mismatches(1);
  const Mismatches none;
  const auto native = static_cast<cudaStream_t>(stream.native());
  mismatches.upload(&none, 1, native);
  const unsigned threads = 256;
  if (floats) {
    // Four launches of 2^30 floats: a grid of 2^22 blocks each.
    const std::uint64_t quarter = std::uint64_t{1} << 30;
    for (std::uint64_t first = 0; first < (std::uint64_t{1} << 32); first += quarter) {
      compare_floats_kernel<<<static_cast<unsigned>(quarter / threads), threads, 0, native>>>(first, quarter,
                                                                                              mismatches.data());
      EXPECT_EQ(cudaGetLastError(), cudaSuccess);
    }
  } else {
    compare_halves_kernel<<<(1u << 16) / threads, threads, 0, native>>>(mismatches.data());
    EXPECT_EQ(cudaGetLastError(), cudaSuccess);
  }
  Mismatches result;
  mismatches.download(&result, 1, native);
  stream.synchronize();
  return result;
}

TEST(HalfCuda, EveryFloatConvertsToTheDefinitionsHalf) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Mismatches m = run(GpuStream::create(Device::cuda(0)), true);
  EXPECT_EQ(m.count, 0u) << "the first float that differs has the bits 0x" << std::hex << m.lowest;
}

TEST(HalfCuda, EveryHalfConvertsToTheDefinitionsFloat) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Mismatches m = run(GpuStream::create(Device::cuda(0)), false);
  EXPECT_EQ(m.count, 0u) << "the first half that differs has the bits 0x" << std::hex << m.lowest;
}

}  // namespace
}  // namespace sls::fusion
