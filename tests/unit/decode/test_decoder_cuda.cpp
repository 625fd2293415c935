// The CUDA decoder equals the CPU decoder (same per-pixel code): masks, projector
// coordinates within 1e-3 px, depth within 0.1 um; and the device-resident entry point gives
// what the host one gives. Skipped without a GPU.
#include <cmath>
#include <cstdio>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "sdk/core/cuda/device_buffer.h"
#include "sdk/decode/cuda/decoder_cuda.h"
#include "sdk/decode/decoder.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

struct Case {
  sim::SimRig rig;
  std::vector<Image16u> stack;
};

Case render_case(const char* object, int width) {
  const sim::Scene scene = sim::make_scene(object);
  sim::RigOptions options;
  options.preset = "ci";
  options.camera_width = width;
  options.frames = 8;
  Case c{sim::make_rig(options, scene), {}};
  sim::Renderer renderer(c.rig, scene, Device::cpu());
  renderer.set_frame(1);
  for (std::size_t k = 0; k < c.rig.patterns.size(); ++k) c.stack.push_back(renderer.render_pattern(static_cast<int>(k)));
  return c;
}

DecodeOptions options() {
  DecodeOptions o;
  o.min_depth_m = 0.09;
  o.max_depth_m = 0.11;
  return o;
}

void expect_equal(const DecodedFrame& cpu, const DecodedFrame& gpu, const char* what) {
  std::size_t mask_differences = 0, compared = 0;
  double worst_u = 0.0, worst_depth = 0.0, worst_confidence = 0.0;
  for (std::size_t i = 0; i < cpu.mask.pixel_count(); ++i) {
    if (cpu.mask.data()[i] != gpu.mask.data()[i]) {
      ++mask_differences;
      continue;
    }
    if (cpu.mask.data()[i] != kDecodeOk) continue;
    ++compared;
    worst_u = std::max(worst_u, std::fabs(static_cast<double>(cpu.projector_u.data()[i] - gpu.projector_u.data()[i])));
    worst_depth = std::max(worst_depth, std::fabs(static_cast<double>(cpu.depth_m.data()[i] - gpu.depth_m.data()[i])));
    worst_confidence =
        std::max(worst_confidence, std::fabs(static_cast<double>(cpu.confidence.data()[i] - gpu.confidence.data()[i])));
  }
  std::printf("[decode-cuda] %s: %zu px compared, %zu mask differences, max |du| %.2e px, max |dz| %.2e um, "
              "max |dconf| %.2e\n",
              what, compared, mask_differences, worst_u, worst_depth * 1e6, worst_confidence);
  // A pixel whose statistic sits within float rounding of a threshold may flip: allow 1e-4.
  EXPECT_LE(mask_differences, cpu.mask.pixel_count() / 10000) << what;
  EXPECT_GT(compared, 1000u) << what;
  EXPECT_LT(worst_u, 1e-3) << what;
  EXPECT_LT(worst_depth, 0.1e-6) << what;
  EXPECT_LT(worst_confidence, 1e-4) << what;
}

TEST(DecoderCuda, EqualsCpu) {
  SLS_REQUIRE_CUDA_DEVICE();
  for (const char* object : {"knurled-screw", "plane", "knurled-knob"}) {
    const Case c = render_case(object, 400);
    Decoder cpu(c.rig.patterns, c.rig.calibration(), Device::cpu(), options());
    Decoder gpu(c.rig.patterns, c.rig.calibration(), Device::cuda(), options());
    expect_equal(cpu.decode(c.stack), gpu.decode(c.stack), object);
  }
}

TEST(DecoderCuda, DeviceResidentStackEqualsHostPath) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Case c = render_case("knurled-screw", 400);
  Decoder gpu(c.rig.patterns, c.rig.calibration(), Device::cuda(), options());
  const DecodedFrame host_path = gpu.decode(c.stack);

  const int width = c.rig.camera.width;
  const int height = c.rig.camera.height;
  const std::size_t pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  // A padded plane stride, as a capture ring buffer might have.
  const std::size_t stride = pixels + 1024;
  std::vector<std::uint16_t> packed(stride * c.stack.size(), 0);
  for (std::size_t k = 0; k < c.stack.size(); ++k) {
    std::copy(c.stack[k].data(), c.stack[k].data() + pixels, packed.begin() + static_cast<std::ptrdiff_t>(k * stride));
  }
  const RayMap& rays = gpu.rays();
  detail::CudaDecodeContext context(gpu.decode_params(), gpu.triangulation_params(), width, height, rays.rays.data(),
                                    rays.valid.data());
  DeviceBuffer<std::uint16_t> stack(packed.size());
  stack.upload(packed.data(), packed.size(), context.stream());
  context.decode_resident(stack.data(), stride);
  DecodedFrame resident;
  resident.projector_u.resize(width, height);
  resident.projector_v.resize(width, height);
  resident.confidence.resize(width, height);
  resident.mask.resize(width, height);
  resident.depth_m.resize(width, height);
  const detail::DecodeOutputsDevice out = context.outputs();
  SLS_CUDA_CHECK(cudaMemcpyAsync(resident.projector_u.data(), out.u, pixels * sizeof(float), cudaMemcpyDeviceToHost,
                                 context.stream()));
  SLS_CUDA_CHECK(cudaMemcpyAsync(resident.confidence.data(), out.confidence, pixels * sizeof(float),
                                 cudaMemcpyDeviceToHost, context.stream()));
  SLS_CUDA_CHECK(cudaMemcpyAsync(resident.mask.data(), out.mask, pixels, cudaMemcpyDeviceToHost, context.stream()));
  SLS_CUDA_CHECK(cudaMemcpyAsync(resident.depth_m.data(), out.depth, pixels * sizeof(float), cudaMemcpyDeviceToHost,
                                 context.stream()));
  SLS_CUDA_CHECK(cudaStreamSynchronize(context.stream()));
  EXPECT_EQ(resident.mask, host_path.mask);
  EXPECT_EQ(resident.depth_m, host_path.depth_m);
}

}  // namespace
}  // namespace sls
