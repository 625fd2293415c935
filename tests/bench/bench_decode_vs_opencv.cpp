// Speed side by side with OpenCV's structured_light GrayCodePattern (issue #4), on the same
// rendered frame as tests/interop/test_decode_vs_opencv.cpp (the knurled screw, demo rig,
// frame 0, rendered once with our default set and OpenCV's Gray set): OpenCV's per-pixel
// getProjPixel over the whole image with its shadow mask, our CPU decoder on our 22 images
// (decode + triangulation), and our CPU decoder on OpenCV's 44 images. The argument is the
// camera width (4:3, the field of view fixed).
#include <benchmark/benchmark.h>

#include <map>
#include <memory>

#include "drivers/sim/renderer.h"
#include "sdk/decode/decoder.h"
#include "tests/interop/opencv_graycode.h"

namespace sls {
namespace {

struct Frame {
  sim::SimRig rig;
  PatternSet ours, gray_only;          // our default set; white, black + OpenCV's Gray set
  std::vector<Image16u> ours_stack, gray_stack;
  std::vector<cv::Mat> opencv_gray;    // 8-bit, OpenCV's order
  cv::Mat opencv_white, opencv_black;
};

const Frame& frame(int camera_width) {
  static std::map<int, std::unique_ptr<Frame>> frames;
  auto& slot = frames[camera_width];
  if (slot) return *slot;
  slot = std::make_unique<Frame>();
  Frame& f = *slot;
  const sim::Scene scene = sim::make_scene("knurled-screw");
  sim::RigOptions options;
  options.preset = "demo";
  options.camera_width = camera_width;
  f.rig = sim::make_rig(options, scene);
  f.ours = f.rig.patterns;
  const PatternSet opencv_set = test::opencv_graycode_pattern_set(f.ours.projector_width, f.ours.projector_height, false);
  f.gray_only = opencv_set;
  f.gray_only.patterns.insert(f.gray_only.patterns.begin(), f.ours.patterns.begin(), f.ours.patterns.begin() + 2);
  sim::SimRig render_rig = f.rig;
  render_rig.patterns.patterns.insert(render_rig.patterns.patterns.end(), opencv_set.patterns.begin(),
                                      opencv_set.patterns.end());
  sim::Renderer renderer(render_rig, scene, default_device());
  renderer.set_frame(0);
  for (int k = 0; k < static_cast<int>(render_rig.patterns.size()); ++k) {
    Image16u image = renderer.render_pattern(k);
    const std::size_t index = static_cast<std::size_t>(k);
    if (index < f.ours.size()) {
      f.ours_stack.push_back(image);
      if (index < 2) f.gray_stack.push_back(image);
    } else {
      f.gray_stack.push_back(image);
      f.opencv_gray.push_back(test::to_opencv_8bit(image, 12));
    }
  }
  f.opencv_white = test::to_opencv_8bit(f.ours_stack[0], 12);
  f.opencv_black = test::to_opencv_8bit(f.ours_stack[1], 12);
  return f;
}

void set_counters(benchmark::State& state, const Frame& f, std::size_t decoded, std::size_t images) {
  const double pixels = static_cast<double>(f.ours_stack[0].pixel_count());
  state.counters["Mpixel"] = pixels / 1e6;
  state.counters["images"] = static_cast<double>(images);
  state.counters["decoded_fraction"] = static_cast<double>(decoded) / pixels;
}

void BM_OpenCvGrayCodePattern(benchmark::State& state) {
  const Frame& f = frame(static_cast<int>(state.range(0)));
  cv::structured_light::GrayCodePattern::Params params;
  params.width = f.ours.projector_width;
  params.height = f.ours.projector_height;
  const auto graycode = cv::structured_light::GrayCodePattern::create(params);
  std::size_t decoded = 0;
  for (auto _ : state) {
    decoded = test::decode_with_opencv(graycode, f.opencv_gray, f.opencv_white, f.opencv_black).decoded;
  }
  set_counters(state, f, decoded, f.opencv_gray.size() + 2);
}

void BM_OursCpuDefaultSet(benchmark::State& state) {
  const Frame& f = frame(static_cast<int>(state.range(0)));
  Decoder decoder(f.ours, f.rig.calibration(), Device::cpu());
  std::size_t decoded = 0;
  for (auto _ : state) decoded = decoder.decode(f.ours_stack).ok_count();
  set_counters(state, f, decoded, f.ours_stack.size());
}

void BM_OursCpuOpenCvImages(benchmark::State& state) {
  const Frame& f = frame(static_cast<int>(state.range(0)));
  Decoder decoder(f.gray_only, f.rig.calibration(), Device::cpu());
  std::size_t decoded = 0;
  for (auto _ : state) decoded = decoder.decode(f.gray_stack).ok_count();
  set_counters(state, f, decoded, f.gray_stack.size());
}

BENCHMARK(BM_OpenCvGrayCodePattern)->Arg(800)->Arg(2000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_OursCpuDefaultSet)->Arg(800)->Arg(2000)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_OursCpuOpenCvImages)->Arg(800)->Arg(2000)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace sls

BENCHMARK_MAIN();
