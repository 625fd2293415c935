// The decoder's frame-level check (stack_check.h): a stack with one pattern image stuck or out
// of place is refused with the image named, while genuine stacks pass — noisy, through a
// projector fed video (gamma 2.2) and a camera with a non-linear response. Without the check
// the same stacks decode to mostly "valid" pixels that are far off: what it prevents.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "sdk/core/error.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/stack_check.h"

namespace sls {
namespace {

struct Rendered {
  sim::SimRig rig;
  std::vector<Image16u> stack;
  sim::GroundTruthFrame truth;
};

Rendered render_screw(double projector_gamma = 1.0, double camera_gamma = 1.0) {
  const sim::Scene scene = sim::make_knurled_screw_scene();
  sim::RigOptions options;
  options.preset = "ci";
  options.camera_width = 200;
  options.frames = 8;
  options.projector_gamma = projector_gamma;
  options.gamma = camera_gamma;
  Rendered r{sim::make_rig(options, scene), {}, {}};
  sim::Renderer renderer(r.rig, scene, Device::cpu());
  renderer.set_frame(0);
  for (std::size_t k = 0; k < r.rig.patterns.size(); ++k) {
    r.stack.push_back(renderer.render_pattern(static_cast<int>(k)));
  }
  r.truth = renderer.ground_truth();
  return r;
}

const Rendered& screw() {
  static const Rendered rendered = render_screw();
  return rendered;
}

Image16u constant_image(const Image16u& like, std::uint16_t value) {
  Image16u image(like.width(), like.height());
  std::fill(image.data(), image.data() + image.pixel_count(), value);
  return image;
}

std::string refusal(Decoder& decoder, const std::vector<Image16u>& stack) {
  try {
    decoder.decode(stack);
  } catch (const Error& e) {
    EXPECT_EQ(e.code(), ErrorCode::kFormat) << e.what();
    return e.what();
  }
  ADD_FAILURE() << "the stack was decoded";
  return {};
}

// Valid pixels, and those more than 100 um off the true depth.
struct DepthFigures {
  std::size_t valid = 0;
  std::size_t far_off = 0;
};
DepthFigures depth_figures(const DecodedFrame& decoded, const sim::GroundTruthFrame& truth) {
  DepthFigures figures;
  for (std::size_t i = 0; i < decoded.depth_m.pixel_count(); ++i) {
    const float depth = decoded.depth_m.data()[i];
    const float true_depth = truth.depth_m.data()[i];
    if (depth <= 0.0f || !(true_depth > 0.0f)) continue;
    ++figures.valid;
    if (std::abs(depth - true_depth) > 100e-6f) ++figures.far_off;
  }
  return figures;
}

TEST(StackCheck, GenuineStacksPass) {
  Decoder decoder(screw().rig.patterns, screw().rig.calibration());
  EXPECT_NO_THROW(check_stack_behaves(screw().rig.patterns, decoder.decode_params(), screw().stack));
  for (const auto& [projector_gamma, camera_gamma] : {std::pair{2.2, 1.0}, std::pair{1.0, 0.6}, std::pair{1.0, 1.6}}) {
    const Rendered bent = render_screw(projector_gamma, camera_gamma);
    EXPECT_NO_THROW(check_stack_behaves(bent.rig.patterns, decoder.decode_params(), bent.stack))
        << "projector gamma " << projector_gamma << ", camera gamma " << camera_gamma;
  }
}

TEST(StackCheck, StuckGrayImageIsRefusedNamingIt) {
  Decoder decoder(screw().rig.patterns, screw().rig.calibration());
  std::vector<Image16u> stack = screw().stack;
  stack[2] = constant_image(stack[2], 2048);  // the coarsest Gray bit stuck at a mid-grey
  const std::string message = refusal(decoder, stack);
  EXPECT_NE(message.find("pattern images 2 (gray_c9) and 3 (gray_c9_inv)"), std::string::npos) << message;
  EXPECT_NE(message.find("stuck"), std::string::npos) << message;

  // What the check prevents: decoded anyway, most pixels are "valid" and many far off.
  DecodeOptions unchecked;
  unchecked.check_stack = false;
  Decoder blind(screw().rig.patterns, screw().rig.calibration(), Device::cpu(), unchecked);
  const DepthFigures figures = depth_figures(blind.decode(stack), screw().truth);
  EXPECT_GT(figures.valid, 1000u);
  EXPECT_GT(figures.far_off, figures.valid / 10) << figures.far_off << " of " << figures.valid;
}

TEST(StackCheck, StuckOrRepeatedPhaseImageIsRefusedNamingIt) {
  Decoder decoder(screw().rig.patterns, screw().rig.calibration());
  std::vector<Image16u> stack = screw().stack;
  stack[17] = constant_image(stack[17], 2048);
  std::string message = refusal(decoder, stack);
  EXPECT_NE(message.find("pattern image 17 (phase_c_p32_s3of8)"), std::string::npos) << message;
  stack = screw().stack;
  stack[17] = stack[16];  // one step shown twice
  message = refusal(decoder, stack);
  EXPECT_NE(message.find("pattern image 17"), std::string::npos) << message;
}

TEST(StackCheck, ImagesOutOfOrderAreRefused) {
  Decoder decoder(screw().rig.patterns, screw().rig.calibration());
  std::vector<Image16u> stack = screw().stack;
  std::swap(stack[4], stack[15]);  // Gray bit 8 and a phase step change places
  const std::string message = refusal(decoder, stack);
  EXPECT_NE(message.find("do not add up"), std::string::npos) << message;
}

TEST(StackCheck, AWrongWhiteImageAloneDoesNotCondemnTheStack) {
  // The decoder barely uses the white image (the shadow test); the complementary pairs agree
  // among themselves, so the stack is judged by them and decodes.
  Decoder decoder(screw().rig.patterns, screw().rig.calibration());
  std::vector<Image16u> stack = screw().stack;
  stack[0] = constant_image(stack[0], 2048);
  EXPECT_NO_THROW(check_stack_behaves(screw().rig.patterns, decoder.decode_params(), stack));
}

TEST(StackCheck, TooFewLitPixelsIsNotJudged) {
  Decoder decoder(screw().rig.patterns, screw().rig.calibration());
  std::vector<Image16u> stack = screw().stack;
  for (std::size_t k = 2; k < stack.size(); ++k) stack[k] = constant_image(stack[k], 2048);
  stack[0] = constant_image(stack[0], 40);  // white barely above black: nothing lit
  stack[1] = constant_image(stack[1], 32);
  EXPECT_NO_THROW(check_stack_behaves(screw().rig.patterns, decoder.decode_params(), stack));
}

// The pixels the check reads (stack_check_shared.h, the CPU's and the GPU's gather): 64 rows
// (every row of a shorter image) in equal bands, at most max_samples in all, spanning each row.
TEST(StackCheckGrid, SpansTheImageInEvenlySpacedRows) {
  for (const auto& [width, height] : {std::pair{200, 150}, std::pair{1200, 900}, std::pair{4000, 3000},
                                      std::pair{50, 20}}) {
    const StackCheckGrid grid = make_stack_check_grid(width, height, 32768);
    SCOPED_TRACE(std::to_string(width) + "x" + std::to_string(height));
    EXPECT_EQ(grid.rows, std::min(height, 64));
    EXPECT_LE(grid.count(), 32768u);
    EXPECT_GE(grid.columns * grid.stride, width);
    EXPECT_LT((grid.columns - 1) * grid.stride, width);
    std::size_t previous_row = 0;
    for (std::size_t n = 0; n < grid.count(); ++n) {
      const std::size_t pixel = grid.pixel(n);
      ASSERT_LT(pixel, static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
      const std::size_t row = pixel / static_cast<std::size_t>(width);
      if (n % static_cast<std::size_t>(grid.columns) == 0) {
        if (n > 0) {
          EXPECT_GT(row, previous_row);
        }
        previous_row = row;
      }
      EXPECT_EQ(row, previous_row);
    }
  }
  EXPECT_EQ(make_stack_check_grid(4000, 3000, 32768).stride, 8);
}

}  // namespace
}  // namespace sls
