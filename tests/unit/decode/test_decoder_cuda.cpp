// The CUDA decoder equals the CPU decoder (same per-pixel code): masks, projector
// coordinates within 1e-3 px, depth within 0.1 um; and the device-resident entry point gives
// what the host one gives. Skipped without a GPU.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <future>
#include <memory>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"
#include "sdk/core/error.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/ray_map.h"
#include "sdk/decode/cuda/decoder_cuda.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/stack_check.h"
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

// The context's outputs, copied to the host on its stream (waits).
DecodedFrame download_outputs(const detail::DecoderGpu& context) {
  const int width = context.width(), height = context.height();
  const std::size_t pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  DecodedFrame frame;
  frame.projector_u.resize(width, height);
  frame.projector_v.resize(width, height);
  frame.confidence.resize(width, height);
  frame.mask.resize(width, height);
  frame.depth_m.resize(width, height);
  const detail::DecodeOutputsDevice out = context.outputs();
  SLS_CUDA_CHECK(cudaMemcpyAsync(frame.projector_u.data(), out.u, pixels * sizeof(float), cudaMemcpyDeviceToHost,
                                 cuda_stream(context.stream())));
  SLS_CUDA_CHECK(cudaMemcpyAsync(frame.projector_v.data(), out.v, pixels * sizeof(float), cudaMemcpyDeviceToHost,
                                 cuda_stream(context.stream())));
  SLS_CUDA_CHECK(cudaMemcpyAsync(frame.confidence.data(), out.confidence, pixels * sizeof(float),
                                 cudaMemcpyDeviceToHost, cuda_stream(context.stream())));
  SLS_CUDA_CHECK(cudaMemcpyAsync(frame.mask.data(), out.mask, pixels, cudaMemcpyDeviceToHost, cuda_stream(context.stream())));
  SLS_CUDA_CHECK(cudaMemcpyAsync(frame.depth_m.data(), out.depth, pixels * sizeof(float), cudaMemcpyDeviceToHost,
                                 cuda_stream(context.stream())));
  SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(context.stream())));
  return frame;
}

// A decoder's device state on its own, as a Decoder on the GPU makes it: the camera's shared
// ray map, a decode and an upload stream.
std::unique_ptr<detail::DecoderGpu> cuda_context(const Decoder& decoder, const CameraIntrinsics& camera) {
  const Device gpu = Device::cuda(0);
  return std::make_unique<detail::DecoderGpu>(decoder.decode_params(), decoder.triangulation_params(),
                                                     shared_ray_map(camera, gpu), GpuStream::create(gpu),
                                                     GpuStream::create(gpu));
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
  const auto context_owner = cuda_context(gpu, c.rig.camera);
  detail::DecoderGpu& context = *context_owner;
  DeviceBuffer<std::uint16_t> stack(packed.size());
  stack.upload(packed.data(), packed.size(), cuda_stream(context.stream()));
  context.decode_resident(stack.data(), stride);
  const DecodedFrame resident = download_outputs(context);
  EXPECT_EQ(resident.mask, host_path.mask);
  EXPECT_EQ(resident.depth_m, host_path.depth_m);
}

// The two-slot pipeline: three different stacks (frames 1..3 of a turntable scan) uploaded
// from pinned memory ahead of their decodes, so uploads overlap decodes and slot 0 is reused
// while slot 1's stack is decoded; each result equals the CPU decoder's on that stack.
TEST(DecoderCuda, PipelinedUploadsGiveEachStacksOwnResult) {
  SLS_REQUIRE_CUDA_DEVICE();
  const sim::Scene scene = sim::make_scene("knurled-screw");
  sim::RigOptions rig_options;
  rig_options.preset = "ci";
  rig_options.camera_width = 400;
  rig_options.frames = 8;
  const sim::SimRig rig = sim::make_rig(rig_options, scene);
  sim::Renderer renderer(rig, scene, Device::cpu());
  const std::size_t count = rig.patterns.size();
  const std::size_t pixels = static_cast<std::size_t>(rig.camera.width) * static_cast<std::size_t>(rig.camera.height);
  std::uint16_t* pinned = nullptr;
  SLS_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&pinned), 3 * count * pixels * sizeof(std::uint16_t)));
  std::vector<std::vector<Image16u>> stacks(3);
  std::vector<std::vector<const std::uint16_t*>> planes(3);
  for (int f = 0; f < 3; ++f) {
    renderer.set_frame(f + 1);
    for (std::size_t k = 0; k < count; ++k) {
      stacks[static_cast<std::size_t>(f)].push_back(renderer.render_pattern(static_cast<int>(k)));
      std::uint16_t* plane = pinned + (static_cast<std::size_t>(f) * count + k) * pixels;
      std::copy(stacks[static_cast<std::size_t>(f)].back().data(), stacks[static_cast<std::size_t>(f)].back().data() + pixels, plane);
      planes[static_cast<std::size_t>(f)].push_back(plane);
    }
  }
  Decoder cpu(rig.patterns, rig.calibration(), Device::cpu(), options());
  const auto context_owner = cuda_context(cpu, rig.camera);
  detail::DecoderGpu& context = *context_owner;
  // The same stacks in pageable memory (the images themselves) go through the pinned staging
  // planes: 22 planes through 3, each reused while the copy engine may still read another.
  std::vector<std::vector<const std::uint16_t*>> pageable(3);
  for (std::size_t f = 0; f < 3; ++f) {
    for (const Image16u& image : stacks[f]) pageable[f].push_back(image.data());
  }
  for (const bool from_pinned : {true, false}) {
    const auto& source = from_pinned ? planes : pageable;
    std::vector<DecodedFrame> gpu;
    int slot = context.upload_async(source[0].data());
    for (std::size_t f = 0; f < 3; ++f) {
      const int next = f + 1 < 3 ? context.upload_async(source[f + 1].data()) : -1;  // overlaps the decode below
      context.decode_slot(slot);
      gpu.push_back(download_outputs(context));
      slot = next;
    }
    for (std::size_t f = 0; f < 3; ++f) {
      const std::string what = std::string(from_pinned ? "pinned" : "pageable") + " pipelined frame " + std::to_string(f + 1);
      expect_equal(cpu.decode(stacks[f]), gpu[f], what.c_str());
    }
    EXPECT_NE(gpu[0].depth_m, gpu[1].depth_m);  // the frames differ, so a stale slot would show
  }
  SLS_CUDA_CHECK(cudaFreeHost(pinned));
}

// What a scan decodes each frame into: depth and confidence only, into one reused
// DecodedFrame; two different frames in a row each equal the full decode's. A GPU scan leaves
// them on the device (final when decode returns, the frame's images untouched) and downloads
// the depth map on demand, equal to the host decode's; before any decode that is a clear error.
TEST(DecoderCuda, DepthAndConfidenceIntoAReusedFrameOrLeftOnTheDevice) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Case a = render_case("knurled-screw", 400);
  const Case b = render_case("knurled-knob", 400);
  Decoder gpu(a.rig.patterns, a.rig.calibration(), Device::cuda(), options());
  DecodedFrame reused, kept;
  EXPECT_THROW(gpu.download_depth(&kept.depth_m), Error);
  for (const Case* c : {&a, &b}) {
    const DecodedFrame full = gpu.decode(c->stack);
    gpu.decode(c->stack, DecodeOutputs::kDepthAndConfidence, &reused);
    EXPECT_EQ(reused.depth_m, full.depth_m);
    EXPECT_EQ(reused.confidence, full.confidence);
    EXPECT_TRUE(reused.projector_u.empty() && reused.projector_v.empty() && reused.mask.empty());

    const Image32f before = kept.depth_m;
    gpu.decode(c->stack, DecodeOutputs::kDepthAndConfidenceOnDevice, &kept);
    EXPECT_EQ(kept.depth_m, before);  // nothing downloaded by the decode
    EXPECT_TRUE(kept.confidence.empty());
    std::vector<float> on_device(full.confidence.pixel_count());
    SLS_CUDA_CHECK(cudaMemcpy(on_device.data(), gpu.confidence_on_device()->data(), on_device.size() * sizeof(float),
                              cudaMemcpyDeviceToHost));
    EXPECT_TRUE(std::equal(on_device.begin(), on_device.end(), full.confidence.data()));
    gpu.download_depth(&kept.depth_m);
    EXPECT_EQ(kept.depth_m, full.depth_m);
  }
}

// The stack check runs where the stack lands (cuda/stack_check.cu):
// every stack the CPU decoder refuses, the CUDA one refuses with the same error, leaving the
// caller's frame as it was, and decodes the next good stack as the CPU does. 1200 px wide, so
// that the check's grid skips pixels (stack_check_shared.h) as at 12 MP.
TEST(DecoderCuda, RefusesWhatTheCpuRefusesAndKeepsTheFrame) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Case c = render_case("knurled-screw", 1200);
  Decoder cpu(c.rig.patterns, c.rig.calibration(), Device::cpu(), options());
  Decoder gpu(c.rig.patterns, c.rig.calibration(), Device::cuda(), options());
  const auto constant = [](const Image16u& like, std::uint16_t value) {
    Image16u image(like.width(), like.height());
    std::fill(image.data(), image.data() + image.pixel_count(), value);
    return image;
  };
  struct Bad {
    const char* what;
    std::vector<Image16u> stack;
  };
  std::vector<Bad> bad;
  bad.push_back({"a stuck Gray image", c.stack});
  bad.back().stack[2] = constant(c.stack[2], 2048);
  bad.push_back({"a stuck phase image", c.stack});
  bad.back().stack[17] = constant(c.stack[17], 2048);
  bad.push_back({"a phase step shown twice", c.stack});
  bad.back().stack[17] = c.stack[16];
  bad.push_back({"images out of order", c.stack});
  std::swap(bad.back().stack[4], bad.back().stack[15]);
  bad.push_back({"an all-dark stack", {}});
  for (const Image16u& image : c.stack) bad.back().stack.push_back(constant(image, 0));

  const auto refusal = [](Decoder& decoder, const std::vector<Image16u>& stack, DecodedFrame* frame) {
    try {
      decoder.decode(stack, DecodeOutputs::kDepthAndConfidence, frame);
    } catch (const Error& e) {
      return std::string(error_code_name(e.code())) + ": " + e.what();
    }
    return std::string("decoded");
  };
  DecodedFrame frame;
  gpu.decode(c.stack, DecodeOutputs::kDepthAndConfidence, &frame);
  const DecodedFrame before = frame;
  for (const Bad& b : bad) {
    DecodedFrame cpu_frame;
    const std::string expected = refusal(cpu, b.stack, &cpu_frame);
    EXPECT_NE(expected, "decoded") << b.what;
    EXPECT_EQ(refusal(gpu, b.stack, &frame), expected) << b.what;
    EXPECT_EQ(frame.depth_m, before.depth_m) << b.what;
    EXPECT_EQ(frame.confidence, before.confidence) << b.what;
  }
  // Without the check, only the all-dark test refuses; with it, a good stack after the refusals.
  DecodeOptions unchecked = options();
  unchecked.check_stack = false;
  Decoder blind(c.rig.patterns, c.rig.calibration(), Device::cuda(), unchecked);
  EXPECT_EQ(refusal(blind, bad.front().stack, &frame), "decoded");
  EXPECT_NE(refusal(blind, bad.back().stack, &frame), "decoded");
  expect_equal(cpu.decode(c.stack), gpu.decode(c.stack), "a good stack after refusals");
}

// The stack check judged where the stack lands: for a genuine stack and for one with a stuck
// phase image, the GPU's histograms and lit count are the host's to the bit (the same per-pixel
// code, compiled without fused multiply-adds), so its verdicts and messages are the CPU's.
TEST(DecoderCuda, StackCheckHistogramsEqualTheHosts) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Case c = render_case("knurled-screw", 1200);
  Decoder cpu(c.rig.patterns, c.rig.calibration(), Device::cpu(), options());
  const StackCheckPlan plan = make_stack_check_plan(cpu.decode_params());
  ASSERT_TRUE(plan.usable);
  ASSERT_GT(plan.slot_count, 0);
  const int width = c.rig.camera.width, height = c.rig.camera.height;
  const StackCheckGrid grid = make_stack_check_grid(width, height, StackCheckLimits{}.max_samples);
  const auto context_owner = cuda_context(cpu, c.rig.camera);
  detail::DecoderGpu& context = *context_owner;
  std::vector<Image16u> stuck = c.stack;
  std::fill(stuck[17].data(), stuck[17].data() + stuck[17].pixel_count(), std::uint16_t{2048});
  const std::vector<Image16u>& genuine = c.stack;
  for (const std::vector<Image16u>* stack : {&genuine, static_cast<const std::vector<Image16u>*>(&stuck)}) {
    std::vector<const std::uint16_t*> planes;
    for (const Image16u& image : *stack) planes.push_back(image.data());
    const int slot = context.upload_async(planes.data());
    context.gather_check_async(slot, grid, plan);
    context.decode_slot(slot);
    const detail::StackCheckInputs gpu = context.wait_check();
    const StackCheckHistograms host = stack_check_histograms(plan, grid, *stack);
    ASSERT_NE(gpu.counts, nullptr);
    EXPECT_GT(host.lit, grid.count() / 4);
    EXPECT_EQ(gpu.lit, host.lit);
    EXPECT_TRUE(std::equal(host.counts.begin(), host.counts.end(), gpu.counts));
    context.synchronize();
  }
}

// A live scan uploads frame n + 1 on another thread while it decodes frame n
// (Decoder::prefetch): each decode takes its own stack, prefetched or not, and equals the CPU's.
TEST(DecoderCuda, StacksUploadedAheadOnAnotherThreadDecodeAsTheirOwn) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Case a = render_case("knurled-screw", 400);
  const Case b = render_case("knurled-knob", 400);
  const Case c = render_case("plane", 400);
  Decoder cpu(a.rig.patterns, a.rig.calibration(), Device::cpu(), options());
  Decoder gpu(a.rig.patterns, a.rig.calibration(), Device::cuda(), options());
  const std::vector<const Case*> frames = {&a, &b, &c, &a, &b};
  for (std::size_t i = 0; i < frames.size(); ++i) {
    std::future<bool> ahead;
    if (i + 1 < frames.size()) {
      ahead = std::async(std::launch::async, [&gpu, &frames, i] { return gpu.prefetch(frames[i + 1]->stack); });
    }
    const DecodedFrame decoded = gpu.decode(frames[i]->stack);
    if (ahead.valid()) {
      EXPECT_TRUE(ahead.get()) << "frame " << i + 1;
    }
    expect_equal(cpu.decode(frames[i]->stack), decoded, ("frame " + std::to_string(i)).c_str());
  }
  // A prefetch not taken is replaced by the next; each stack still decodes as its own.
  EXPECT_TRUE(gpu.prefetch(b.stack));
  EXPECT_TRUE(gpu.prefetch(c.stack));
  expect_equal(cpu.decode(b.stack), gpu.decode(b.stack), "a stack whose prefetch was replaced");
  expect_equal(cpu.decode(c.stack), gpu.decode(c.stack), "the prefetch that replaced it");
  // What decode() would refuse for its count or sizes is not uploaded; a CPU decoder uploads nothing.
  std::vector<Image16u> short_stack(a.stack.begin(), a.stack.end() - 1);
  EXPECT_FALSE(gpu.prefetch(short_stack));
  std::vector<Image16u> small;
  for (std::size_t k = 0; k < a.stack.size(); ++k) small.emplace_back(8, 8);
  EXPECT_FALSE(gpu.prefetch(small));
  EXPECT_FALSE(cpu.prefetch(a.stack));
}

// A stack captured into page-locked memory (a camera's images for a GPU scan) is uploaded
// without staging and decodes as the pageable one does, to the bit; its images may be
// overwritten as soon as prefetch() returns (the copy engine has read them by then).
TEST(DecoderCuda, APageLockedStackDecodesAsThePageableOneAndIsFreeOncePrefetched) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Case a = render_case("knurled-screw", 400);
  std::vector<Image16u> pinned;
  for (const Image16u& image : a.stack) {
    pinned.emplace_back(MemoryType::kPinned);
    pinned.back().resize(image.width(), image.height());
    std::copy(image.data(), image.data() + image.pixel_count(), pinned.back().data());
    ASSERT_EQ(pinned.back().memory_type(), MemoryType::kPinned);
  }
  // Bit for bit (not ==: invalid pixels are NaN in the float maps).
  const auto same_bits = [](const auto& left, const auto& right) {
    return left.size_bytes() == right.size_bytes() && std::memcmp(left.data(), right.data(), left.size_bytes()) == 0;
  };
  Decoder gpu(a.rig.patterns, a.rig.calibration(), Device::cuda(), options());
  const DecodedFrame from_pageable = gpu.decode(a.stack);
  const DecodedFrame from_pinned = gpu.decode(pinned);
  EXPECT_TRUE(same_bits(from_pinned.mask, from_pageable.mask));
  EXPECT_TRUE(same_bits(from_pinned.depth_m, from_pageable.depth_m));
  EXPECT_TRUE(same_bits(from_pinned.projector_u, from_pageable.projector_u));
  // Prefetched, then the images scribbled over before the decode takes the upload.
  ASSERT_TRUE(gpu.prefetch(pinned));
  for (Image16u& image : pinned) std::fill(image.data(), image.data() + image.pixel_count(), std::uint16_t{0});
  const DecodedFrame prefetched = gpu.decode(pinned);  // the same planes: the prefetched upload
  EXPECT_TRUE(same_bits(prefetched.mask, from_pageable.mask));
  EXPECT_TRUE(same_bits(prefetched.depth_m, from_pageable.depth_m));
}

// The context's slots: a prefetched stack is taken once, by its own planes only; with both
// slots held there is none to prefetch into.
TEST(DecoderCuda, APrefetchedStackIsTakenOnceByItsOwnPlanes) {
  SLS_REQUIRE_CUDA_DEVICE();
  const Case a = render_case("knurled-screw", 400);
  const Case b = render_case("knurled-knob", 400);
  Decoder cpu(a.rig.patterns, a.rig.calibration(), Device::cpu(), options());
  const auto context_owner = cuda_context(cpu, a.rig.camera);
  detail::DecoderGpu& context = *context_owner;
  std::vector<const std::uint16_t*> planes_a, planes_b;
  for (const Image16u& image : a.stack) planes_a.push_back(image.data());
  for (const Image16u& image : b.stack) planes_b.push_back(image.data());
  EXPECT_EQ(context.take_prefetched(planes_a.data()), -1);
  ASSERT_TRUE(context.prefetch(planes_a.data()));
  EXPECT_EQ(context.take_prefetched(planes_b.data()), -1);
  const int slot_a = context.take_prefetched(planes_a.data());
  ASSERT_GE(slot_a, 0);
  EXPECT_EQ(context.take_prefetched(planes_a.data()), -1);
  const int slot_b = context.upload_async(planes_b.data());
  EXPECT_NE(slot_b, slot_a);
  EXPECT_FALSE(context.prefetch(planes_a.data()));  // both slots hold stacks not yet decoded
  try {
    context.upload_async(planes_a.data());
    ADD_FAILURE() << "a third stack was uploaded into two slots";
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kInvalidArgument) << e.what();
  }
  context.decode_slot(slot_a);
  expect_equal(cpu.decode(a.stack), download_outputs(context), "the prefetched stack");
  context.decode_slot(slot_b);
  expect_equal(cpu.decode(b.stack), download_outputs(context), "the one uploaded beside it");
  EXPECT_TRUE(context.prefetch(planes_a.data()));  // the slots are free again
}

}  // namespace
}  // namespace sls
