#include <vector>

#include "sdk/core/cuda/cuda_check.h"
#include "sdk/core/cuda/device_buffer.h"
#include "tests/unit/sim/shared_math_cases.h"

namespace sls::sim::test {
namespace {

__global__ void evaluate_kernel(int count, PatternDesc pattern, PatternLevelTable table, CaseResult* results) {
  const int i = static_cast<int>(blockIdx.x * blockDim.x + threadIdx.x);
  if (i < count) evaluate_case(i, count, pattern, table, &results[i]);
}

}  // namespace

void evaluate_cases_cuda(int count, const PatternDesc& pattern, const std::uint8_t* levels, CaseResult* results) {
  cudaStream_t stream = nullptr;
  SLS_CUDA_CHECK(cudaStreamCreate(&stream));
  DeviceBuffer<std::uint8_t> device_levels(static_cast<std::size_t>(pattern.extent));
  DeviceBuffer<CaseResult> device_results(static_cast<std::size_t>(count));
  device_levels.upload(levels, static_cast<std::size_t>(pattern.extent), stream);
  const PatternLevelTable table{device_levels.data(), pattern.extent};
  const int block = 128;
  evaluate_kernel<<<(count + block - 1) / block, block, 0, stream>>>(count, pattern, table, device_results.data());
  SLS_CUDA_CHECK_LAUNCH();
  device_results.download(results, static_cast<std::size_t>(count), stream);
  SLS_CUDA_CHECK(cudaStreamSynchronize(stream));
  SLS_CUDA_CHECK(cudaStreamDestroy(stream));
}

}  // namespace sls::sim::test
