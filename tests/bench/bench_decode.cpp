// The decode stage at the paper's size: one 22-image stack of 4000x3000 12-bit images
// (the simulated knurled screw, rendered once) decoded and triangulated. CUDA with the stack
// resident on the device (the <= 2 ms target of issue #4), the upload of the stack from
// pinned host memory beside it, host stacks through the overlapped two-slot pipeline, and
// the CPU, and the host-side stack check each decode runs first. Timed with CUDA events on the
// decoder's stream. BM_DecodeFamily*: the same frame in each pattern family of issue 21 (the
// descriptions of samples/patterns/; <= 2 ms resident for heterodyne and micro phase shifting).
#include <benchmark/benchmark.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "drivers/sim/renderer.h"
#include "sdk/core/device.h"
#include "sdk/core/gpu_stream.h"
#include "sdk/core/ray_map.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/pattern_families.h"
#include "sdk/decode/stack_check.h"

#if defined(SLS_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "sdk/core/cuda/cuda_stream.h"
#include "sdk/core/cuda/device_buffer.h"
#include "sdk/decode/cuda/decoder_cuda.h"
#endif

namespace sls {
namespace {

struct Stack {
  sim::SimRig rig;
  std::vector<Image16u> images;
};

// The families of BM_DecodeFamily* (arg = index): slscan's own (the preset's set), then the
// shipped descriptions.
const char* const kFamilies[] = {"",
                                 "heterodyne_3freq.json",
                                 "micro_phase_shifting.json",
                                 "complementary_gray_phase_shift.json",
                                 "multi_period_gray_phase_shift.json",
                                 "opencv_graycode_1024x768.json"};
constexpr int kFamilyCount = static_cast<int>(sizeof(kFamilies) / sizeof(kFamilies[0]));

// Rendered once per process and family (on the GPU when there is one: 22 images in well under
// a second). `description`: a file of samples/patterns/, empty for the preset's own set.
// A C string, not a std::string: a reference returned from a function given a temporary is what
// GCC 13's -Wdangling-reference flags, though the stacks live in the static map.
const Stack& paper_stack(const char* description_file = "") {
  static std::map<std::string, std::unique_ptr<Stack>> stacks;
  const std::string description(description_file);
  std::unique_ptr<Stack>& stack = stacks[description];
  if (stack == nullptr) {
    auto s = std::make_unique<Stack>();
    sim::RigOptions options;
    options.preset = "paper";
    const sim::Scene scene = sim::make_scene("knurled-screw");
    s->rig = sim::make_rig(options, scene);
    if (!description.empty()) {
      sim::use_pattern_set(s->rig, load_pattern_description(std::string(SLS_SOURCE_DIR) + "/samples/patterns/" +
                                                            description));
    }
    sim::Renderer renderer(s->rig, scene, default_device());
    renderer.set_frame(0);
    for (int k = 0; k < static_cast<int>(s->rig.patterns.size()); ++k) s->images.push_back(renderer.render_pattern(k));
    stack = std::move(s);
  }
  return *stack;
}

void BM_DecodeCpu(benchmark::State& state) {
  const Stack& stack = paper_stack();
  Decoder decoder(stack.rig.patterns, stack.rig.calibration(), Device::cpu());
  std::size_t ok = 0;
  for (auto _ : state) ok = decoder.decode(stack.images).ok_count();
  state.counters["Mpixel"] = static_cast<double>(stack.images[0].pixel_count()) / 1e6;
  state.counters["valid_fraction"] = static_cast<double>(ok) / static_cast<double>(stack.images[0].pixel_count());
}
BENCHMARK(BM_DecodeCpu)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

void BM_DecodeFamilyCpu(benchmark::State& state) {
  const Stack& stack = paper_stack(kFamilies[state.range(0)]);
  Decoder decoder(stack.rig.patterns, stack.rig.calibration(), Device::cpu());
  std::size_t ok = 0;
  for (auto _ : state) ok = decoder.decode(stack.images).ok_count();
  state.SetLabel(stack.rig.patterns.name);
  state.counters["images"] = static_cast<double>(stack.images.size());
  state.counters["valid_fraction"] = static_cast<double>(ok) / static_cast<double>(stack.images[0].pixel_count());
}
BENCHMARK(BM_DecodeFamilyCpu)
    ->ArgName("family")
    ->DenseRange(0, kFamilyCount - 1)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Iterations(3);

// The host-side frame check every Decoder::decode runs before decoding (stack_check.h): what it
// adds to each frame of a scan.
void BM_StackCheck(benchmark::State& state) {
  const Stack& stack = paper_stack();
  Decoder decoder(stack.rig.patterns, stack.rig.calibration(), Device::cpu());
  for (auto _ : state) check_stack_behaves(stack.rig.patterns, decoder.decode_params(), stack.images);
  state.counters["Mpixel"] = static_cast<double>(stack.images[0].pixel_count()) / 1e6;
}
BENCHMARK(BM_StackCheck)->Unit(benchmark::kMillisecond)->UseRealTime();


#if defined(SLS_HAVE_CUDA)
class CudaEvents {
 public:
  CudaEvents() {
    SLS_CUDA_CHECK(cudaEventCreate(&start_));
    SLS_CUDA_CHECK(cudaEventCreate(&stop_));
  }
  ~CudaEvents() {
    (void)cudaEventDestroy(start_);
    (void)cudaEventDestroy(stop_);
  }
  void start(cudaStream_t stream) { SLS_CUDA_CHECK(cudaEventRecord(start_, stream)); }
  double stop_ms(cudaStream_t stream) {
    SLS_CUDA_CHECK(cudaEventRecord(stop_, stream));
    SLS_CUDA_CHECK(cudaEventSynchronize(stop_));
    float ms = 0.0f;
    SLS_CUDA_CHECK(cudaEventElapsedTime(&ms, start_, stop_));
    return static_cast<double>(ms);
  }

 private:
  cudaEvent_t start_ = nullptr, stop_ = nullptr;
};

// Pinned host copy of a stack, plane after plane.
struct PinnedStack {
  std::uint16_t* data = nullptr;
  std::size_t pixels = 0;
  explicit PinnedStack(const std::vector<Image16u>& images) : pixels(images[0].pixel_count()) {
    SLS_CUDA_CHECK(cudaMallocHost(reinterpret_cast<void**>(&data), images.size() * pixels * sizeof(std::uint16_t)));
    for (std::size_t k = 0; k < images.size(); ++k) std::copy(images[k].data(), images[k].data() + pixels, data + k * pixels);
  }
  ~PinnedStack() { (void)cudaFreeHost(data); }
  PinnedStack(const PinnedStack&) = delete;
  PinnedStack& operator=(const PinnedStack&) = delete;
};

// The CUDA decode context for a stack's rig, set up from a CPU decoder's parameters and the
// camera's shared ray map, as a GPU decoder sets it up.
struct StackDecodeContext {
  Decoder decoder;
  detail::DecoderGpu context;
  explicit StackDecodeContext(const Stack& stack)
      : decoder(stack.rig.patterns, stack.rig.calibration(), Device::cpu()),
        context(decoder.decode_params(), decoder.triangulation_params(),
                shared_ray_map(stack.rig.camera, Device::cuda(0)), GpuStream::create(Device::cuda(0)),
                GpuStream::create(Device::cuda(0))) {}
};

// The stack resident on the device, decoded and triangulated per iteration (CUDA events).
void time_resident_decode(benchmark::State& state, const Stack& stack) {
  StackDecodeContext stack_context(stack);
  detail::DecoderGpu& context = stack_context.context;
  const std::size_t pixels = stack.images[0].pixel_count();
  const PinnedStack pinned(stack.images);
  DeviceBuffer<std::uint16_t> device_stack(stack.images.size() * pixels);
  device_stack.upload(pinned.data, stack.images.size() * pixels, cuda_stream(context.stream()));
  context.decode_resident(device_stack.data(), pixels);  // warm-up
  SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(context.stream())));
  CudaEvents events;
  for (auto _ : state) {
    events.start(cuda_stream(context.stream()));
    context.decode_resident(device_stack.data(), pixels);
    state.SetIterationTime(events.stop_ms(cuda_stream(context.stream())) * 1e-3);
  }
  state.counters["Mpixel"] = static_cast<double>(pixels) / 1e6;
}

void BM_DecodeCudaResident(benchmark::State& state) {
  if (cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const Stack& stack = paper_stack();
  time_resident_decode(state, stack);
  const std::size_t pixels = stack.images[0].pixel_count();
  const std::size_t stack_bytes = stack.images.size() * pixels * sizeof(std::uint16_t);
  // The fewest bytes: the stack read once, the ray map (16 B/px) read, the outputs (17 B/px) written.
  state.counters["floor_MB"] = static_cast<double>(stack_bytes + pixels * (16 + 17)) / 1e6;
}
BENCHMARK(BM_DecodeCudaResident)->Unit(benchmark::kMillisecond)->UseManualTime();

// Each family's stack resident on the device: decode + triangulate (issue 21: <= 2 ms for
// heterodyne and micro phase shifting at 4000 x 3000). valid_fraction: of all pixels.
void BM_DecodeFamilyCudaResident(benchmark::State& state) {
  if (cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const Stack& stack = paper_stack(kFamilies[state.range(0)]);
  time_resident_decode(state, stack);
  state.SetLabel(stack.rig.patterns.name);
  state.counters["images"] = static_cast<double>(stack.images.size());
  Decoder decoder(stack.rig.patterns, stack.rig.calibration(), Device::cuda());
  state.counters["valid_fraction"] = static_cast<double>(decoder.decode(stack.images).ok_count()) /
                                     static_cast<double>(stack.images[0].pixel_count());
}
BENCHMARK(BM_DecodeFamilyCudaResident)
    ->ArgName("family")
    ->DenseRange(0, kFamilyCount - 1)
    ->Unit(benchmark::kMillisecond)
    ->UseManualTime();

void BM_UploadStackPinned(benchmark::State& state) {
  if (cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const Stack& stack = paper_stack();
  const std::size_t pixels = stack.images[0].pixel_count();
  const PinnedStack pinned(stack.images);
  DeviceBuffer<std::uint16_t> device_stack(stack.images.size() * pixels);
  cudaStream_t stream = nullptr;
  SLS_CUDA_CHECK(cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking));
  CudaEvents events;
  for (auto _ : state) {
    events.start(stream);
    device_stack.upload(pinned.data, stack.images.size() * pixels, stream);
    state.SetIterationTime(events.stop_ms(stream) * 1e-3);
  }
  (void)cudaStreamDestroy(stream);
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(stack.images.size() * pixels * sizeof(std::uint16_t)));
}
BENCHMARK(BM_UploadStackPinned)->Unit(benchmark::kMillisecond)->UseManualTime();

// A pageable stack (the images themselves, as a camera driver or the simulator hands them
// over) through the context's pinned staging planes: the upload alone, wall time until it
// has landed. Beside BM_UploadStackPinned it is the staging's cost.
void BM_UploadStackPageable(benchmark::State& state) {
  if (cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const Stack& stack = paper_stack();
  StackDecodeContext stack_context(stack);
  detail::DecoderGpu& context = stack_context.context;
  std::vector<const std::uint16_t*> planes;
  for (const Image16u& image : stack.images) planes.push_back(image.data());
  context.decode_slot(context.upload_async(planes.data()));  // warm-up: slots and staging allocated
  context.decode_slot(context.upload_async(planes.data()));
  SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(context.stream())));
  for (auto _ : state) {
    context.decode_slot(context.upload_async(planes.data()));
    SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(context.stream())));
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                          static_cast<std::int64_t>(stack.images.size() * stack.images[0].size_bytes()));
}
BENCHMARK(BM_UploadStackPageable)->Unit(benchmark::kMillisecond)->UseRealTime();

// What the scan session does per frame on a GPU: Decoder::decode of a pageable stack into a
// reused frame, depth and confidence downloaded (checks, staging, upload, decode, download).
void BM_DecodeDepthFromPageableStack(benchmark::State& state) {
  if (cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const Stack& stack = paper_stack();
  Decoder decoder(stack.rig.patterns, stack.rig.calibration(), Device::cuda());
  DecodedFrame frame;
  decoder.decode(stack.images, DecodeOutputs::kDepthAndConfidence, &frame);  // warm-up
  for (auto _ : state) decoder.decode(stack.images, DecodeOutputs::kDepthAndConfidence, &frame);
  state.counters["Mpixel"] = static_cast<double>(stack.images[0].pixel_count()) / 1e6;
}
BENCHMARK(BM_DecodeDepthFromPageableStack)->Unit(benchmark::kMillisecond)->UseRealTime();

// Host stacks through the context's two-slot pipeline: 8 stacks per iteration, the upload of
// each overlapping the decode of the one before (arg 1), or each stack uploaded, decoded and
// waited for before the next (arg 0). ms_per_stack is wall time per stack.
void BM_DecodeCudaHostStacks(benchmark::State& state) {
  if (cuda_device_count() == 0) {
    state.SkipWithError("no CUDA device");
    return;
  }
  const bool overlapped = state.range(0) != 0;
  const Stack& stack = paper_stack();
  StackDecodeContext stack_context(stack);
  detail::DecoderGpu& context = stack_context.context;
  const PinnedStack pinned(stack.images);
  std::vector<const std::uint16_t*> planes;
  for (std::size_t k = 0; k < stack.images.size(); ++k) planes.push_back(pinned.data + k * pinned.pixels);
  constexpr int kStacks = 8;
  context.decode_slot(context.upload_async(planes.data()));  // warm-up: allocates both slots' first
  context.decode_slot(context.upload_async(planes.data()));
  SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(context.stream())));
  for (auto _ : state) {
    if (overlapped) {
      int slot = context.upload_async(planes.data());
      for (int n = 0; n < kStacks; ++n) {
        const int next = n + 1 < kStacks ? context.upload_async(planes.data()) : -1;
        context.decode_slot(slot);
        slot = next;
      }
      SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(context.stream())));
    } else {
      for (int n = 0; n < kStacks; ++n) {
        context.decode_slot(context.upload_async(planes.data()));
        SLS_CUDA_CHECK(cudaStreamSynchronize(cuda_stream(context.stream())));
      }
    }
  }
  state.counters["ms_per_stack"] = benchmark::Counter(static_cast<double>(state.iterations()) * kStacks * 1e-3,
                                                      benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["Mpixel"] = static_cast<double>(pinned.pixels) / 1e6;
}
BENCHMARK(BM_DecodeCudaHostStacks)->ArgName("overlapped")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
#endif

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
