// HDR fusion (sdk/decode/hdr_fusion.h): exposure choice per pixel, refused inputs, and on the
// simulator's metal screw the pixels a saturated single exposure loses.
#include <gtest/gtest.h>

#include <cstdio>
#include <functional>

#include "drivers/sim/renderer.h"
#include "drivers/sim/scene.h"
#include "sdk/core/error.h"
#include "sdk/decode/decode_metrics.h"
#include "sdk/decode/hdr_fusion.h"
#include "tests/support/test_support.h"
#include "tests/unit/sim/sim_test_rig.h"

namespace sls {
namespace {

using test::code_of;

TEST(HdrExposures, ParsesAndRefusesBadSettings) {
  EXPECT_EQ(parse_hdr_exposures("1").scales, std::vector<double>({1.0}));
  EXPECT_EQ(parse_hdr_exposures("1,0.125").scales, std::vector<double>({1.0, 0.125}));
  EXPECT_EQ(parse_hdr_exposures("4, 1,0.25,0.0625").count(), 4u);
  for (const char* bad : {"", "0", "1,-0.5", "1,0.5,0.25,0.125,0.0625", "1,1", "1,,2", "x", "1,nan", "1,inf"}) {
    EXPECT_EQ(code_of([&] { parse_hdr_exposures(bad); }), ErrorCode::kInvalidArgument) << "'" << bad << "'";
  }
  HdrExposures none;
  none.scales.clear();
  EXPECT_EQ(code_of([&] { none.validate(); }), ErrorCode::kInvalidArgument);
}

// Two patterns at exposures {0.25, 1} (given shortest first: the order must not matter).
std::vector<Image16u> two_exposures(std::uint16_t long0, std::uint16_t long1, std::uint16_t short0,
                                    std::uint16_t short1) {
  std::vector<Image16u> images(4, Image16u(2, 1, 100));
  images[0](0, 0) = short0;
  images[1](0, 0) = short1;
  images[2](0, 0) = long0;
  images[3](0, 0) = long1;
  return images;
}

TEST(HdrFusion, TakesEachPixelsLongestUnsaturatedExposureUnscaled) {
  const HdrExposures exposures = parse_hdr_exposures("0.25,1");
  HdrFusionOptions options;
  options.check_exposures = false;
  // Pixel 0 unsaturated at the long exposure: its samples, as they are.
  HdrFusedStack fused = fuse_hdr_stack(two_exposures(3000, 1000, 770, 270), 2, exposures, {}, options);
  ASSERT_EQ(fused.images.size(), 2u);
  EXPECT_EQ(fused.images[0](0, 0), 3000);
  EXPECT_EQ(fused.images[1](0, 0), 1000);
  EXPECT_EQ(fused.exposure_index(0, 0), 1);
  EXPECT_EQ(fused.saturated_pixels, 0u);
  // One image saturated at the long exposure (4013 = 98 % of 4095): both from the short one,
  // so a pixel's samples never mix exposures.
  fused = fuse_hdr_stack(two_exposures(4095, 1000, 1030, 270), 2, exposures, {}, options);
  EXPECT_EQ(fused.images[0](0, 0), 1030);
  EXPECT_EQ(fused.images[1](0, 0), 270);
  EXPECT_EQ(fused.exposure_index(0, 0), 0);
  // Saturated at both: the shortest's samples, counted (the decoder flags them saturated).
  fused = fuse_hdr_stack(two_exposures(4095, 4095, 4095, 2000), 2, exposures, {}, options);
  EXPECT_EQ(fused.images[0](0, 0), 4095);
  EXPECT_EQ(fused.images[1](0, 0), 2000);
  EXPECT_EQ(fused.saturated_pixels, 1u);
  // The saturation level is the decoder's.
  DecodeOptions decode;
  decode.saturation_dn = 2500.0;
  fused = fuse_hdr_stack(two_exposures(3000, 1000, 770, 270), 2, exposures, decode, options);
  EXPECT_EQ(fused.exposure_index(0, 0), 0);
}

TEST(HdrFusion, RefusesInconsistentStacks) {
  const HdrExposures exposures = parse_hdr_exposures("1,0.25");
  EXPECT_EQ(code_of([&] { fuse_hdr_stack(std::vector<Image16u>(3, Image16u(2, 2)), 2, exposures); }),
            ErrorCode::kInvalidArgument);  // 3 images for 2 patterns x 2 exposures
  std::vector<Image16u> mixed(4, Image16u(2, 2));
  mixed[3] = Image16u(3, 2);
  EXPECT_EQ(code_of([&] { fuse_hdr_stack(mixed, 2, exposures); }), ErrorCode::kInvalidArgument);
  EXPECT_EQ(code_of([&] { fuse_hdr_stack({}, 0, exposures); }), ErrorCode::kInvalidArgument);
  // Two "exposures" equally bright: the camera ignored the setting.
  std::vector<Image16u> same(4, Image16u(32, 32, 2000));
  try {
    fuse_hdr_stack(same, 2, exposures);
    FAIL() << "equal exposures accepted";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kFormat);
    EXPECT_NE(std::string(error.what()).find("did the camera apply the exposure"), std::string::npos) << error.what();
  }
  // Scaled as they say (above black): accepted.
  std::vector<Image16u> scaled = {Image16u(32, 32, 2032), Image16u(32, 32, 1032), Image16u(32, 32, 532),
                                  Image16u(32, 32, 282)};
  EXPECT_NO_THROW(fuse_hdr_stack(scaled, 2, exposures));
}

// The simulator's metal screw: a saturated single exposure loses its highlights, which the
// short exposure of an HDR capture decodes.
TEST(HdrFusion, MetalScrewHighlightsLostToSaturationAreRecovered) {
  const sim::Scene scene = sim::make_scene("knurled-screw");
  sim::SimRig rig = sim::small_rig(scene, 200);
  ASSERT_TRUE(sim::surface_material_by_name("metal", &rig.material));
  sim::Renderer renderer(rig, scene, Device::cpu());
  renderer.set_frame(0);
  const HdrExposures exposures = parse_hdr_exposures("1,0.25");
  std::vector<Image16u> images;
  for (std::size_t e = 0; e < exposures.count(); ++e) {
    for (int j = 0; j < static_cast<int>(rig.patterns.size()); ++j) {
      images.push_back(renderer.render_pattern(j, exposures.scales[e], static_cast<int>(e)));
    }
  }
  const sim::GroundTruthFrame truth = renderer.ground_truth();
  Decoder decoder(rig.patterns, rig.calibration(), Device::cpu());
  const std::vector<Image16u> single(images.begin(), images.begin() + static_cast<std::ptrdiff_t>(rig.patterns.size()));
  const DecodedFrame one = decoder.decode(single);
  const HdrFusedStack fused = fuse_hdr_stack(images, rig.patterns.size(), exposures);
  const DecodedFrame hdr = decoder.decode(fused.images);
  std::size_t saturated_single = 0, saturated_hdr = 0;
  for (std::size_t i = 0; i < one.mask.pixel_count(); ++i) {
    saturated_single += (one.mask.data()[i] & kDecodeSaturated) != 0;
    saturated_hdr += (hdr.mask.data()[i] & kDecodeSaturated) != 0;
  }
  const DecodeErrorStats stats_one = compare_with_ground_truth(one, truth.projector_u, truth.depth_m, truth.valid);
  const DecodeErrorStats stats_hdr = compare_with_ground_truth(hdr, truth.projector_u, truth.depth_m, truth.valid);
  EXPECT_GT(saturated_single, 100u);  // metal at the nominal exposure clips
  EXPECT_LT(saturated_hdr, saturated_single / 10);
  EXPECT_GT(stats_hdr.valid_fraction(), stats_one.valid_fraction() + 0.05);
  // The recovered pixels decode as well as the rest (not merely pass the decoder's tests).
  EXPECT_LT(stats_hdr.projector_rms_px(), 1.25 * stats_one.projector_rms_px());
  RecordProperty("valid_single", std::to_string(stats_one.valid_fraction()));
  RecordProperty("valid_hdr", std::to_string(stats_hdr.valid_fraction()));
  std::printf("metal screw 200x150: valid single %.3f, HDR %.3f; saturated pixels %zu -> %zu; projector RMS %.4f -> %.4f px\n",
              stats_one.valid_fraction(), stats_hdr.valid_fraction(), saturated_single, saturated_hdr,
              stats_one.projector_rms_px(), stats_hdr.projector_rms_px());
}

}  // namespace
}  // namespace sls
