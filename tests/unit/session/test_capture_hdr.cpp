// HDR capture end to end on the simulator: the sequencer takes the whole stack at each
// exposure through the devices, the recording keeps the exposures, a replay fuses them
// (sdk/session/hdr_frame.h) and the metal screw's highlights decode.
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "drivers/sim/sim_recording.h"
#include "drivers/sim/sim_scanner.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/recording.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/hdr_fusion.h"
#include "sdk/session/capture_sequencer.h"
#include "sdk/session/hdr_frame.h"
#include "tests/support/test_support.h"

namespace sls::session {
namespace {

using test::code_of;

sim::SimRecordingOptions metal_screw(const std::vector<double>& exposures) {
  sim::SimRecordingOptions options;
  options.rig.preset = "ci";
  options.rig.frames = 1;
  options.rig.camera_width = 120;
  options.rig.material = "metal";
  options.exposures = exposures;
  options.reference_spacing_m = 1e-3;
  return options;
}

TEST(HdrCapture, TheSequencersStacksPerExposureAreTheSimulatorsAndTheReplayRecoversHighlights) {
  test::TemporaryDirectory dir;
  const std::vector<double> exposures = {1.0, 0.25};
  const sim::SimRecordingOptions sim_options = metal_screw(exposures);
  sim::write_sim_recording(dir.file("direct"), sim_options, Device::cpu(), {});

  const auto scanner = sim::SimScanner::create(sim_options.object, sim_options.rig, Device::cpu());
  EXPECT_NE(scanner->uri().find("material=metal"), std::string::npos) << scanner->uri();
  auto projector = scanner->projector();
  auto camera = scanner->camera();
  auto turntable = scanner->turntable();
  CaptureOptions options;
  options.frames_per_revolution = 1;
  options.exposures = exposures;
  const PatternSet& set = scanner->rig().patterns;
  RecordingWriterOptions writer_options;
  writer_options.sync = false;
  RecordingWriter writer = RecordingWriter::create(
      dir.file("sequenced"), make_recording_info(*projector, *camera, set, exposures), scanner->rig().calibration(),
      writer_options);
  CaptureSequencer sequencer(*projector, {camera.get()}, turntable.get(), set, options);
  sequencer.run({&writer});
  writer.close();
  EXPECT_EQ(camera->exposure_us(), sim::kSimNominalExposureUs);  // the base restored

  const RecordingReader direct = RecordingReader::open(dir.file("direct"));
  const RecordingReader sequenced = RecordingReader::open(dir.file("sequenced"));
  EXPECT_EQ(sequenced.info().exposures, exposures);
  EXPECT_EQ(direct.info().exposures, exposures);
  EXPECT_EQ(sequenced.info().images_per_frame, static_cast<int>(2 * set.size()));
  EXPECT_NE(read_file_text(dir.file("sequenced/manifest.json")).find("\"format_version\": 2"), std::string::npos);
  ASSERT_EQ(sequenced.frame_count(), 1u);
  const std::vector<Image16u> a = direct.load_images(0);
  const std::vector<Image16u> b = sequenced.load_images(0);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) EXPECT_TRUE(a[k] == b[k]) << "image " << k;

  // The replay's fusion: one stack, a texture, and pixels the nominal exposure loses decoded.
  ScanFrame frame;
  frame.images = b;
  DecodeOptions decode;
  fuse_hdr_frame(sequenced.info(), decode, &frame);
  ASSERT_EQ(frame.images.size(), set.size());
  ASSERT_TRUE(frame.texture.has_value());
  Decoder decoder(set, sequenced.calibration(), Device::cpu(), decode);
  const std::vector<Image16u> nominal(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(set.size()));
  const std::size_t single = decoder.decode(nominal).ok_count();
  const std::size_t hdr = decoder.decode(frame.images).ok_count();
  EXPECT_GT(hdr, single + single / 20) << "single " << single << ", HDR " << hdr;
}

TEST(HdrCapture, BadExposureSettingsAreRefused) {
  for (const std::vector<double>& bad : std::vector<std::vector<double>>{
           {0.0}, {1.0, -1.0}, {1.0, 1.0}, {1.0, 0.5, 0.25, 0.125, 0.0625}, {1.0, std::nan("")}}) {
    CaptureOptions options;
    options.exposures = bad;
    EXPECT_EQ(code_of([&] { options.validate(); }), ErrorCode::kInvalidArgument) << bad.size();
  }
  test::TemporaryDirectory dir;
  RecordingInfo info;
  info.camera = {8, 6, 12};
  info.images_per_frame = 5;
  info.exposures = {1.0, 0.25};  // 5 images are not a whole stack per exposure
  EXPECT_EQ(code_of([&] { RecordingWriter::create(dir.file("a"), info, std::nullopt); }), ErrorCode::kInvalidArgument);
  info.images_per_frame = 4;
  info.exposures = {1.0, 0.0};
  EXPECT_EQ(code_of([&] { RecordingWriter::create(dir.file("b"), info, std::nullopt); }), ErrorCode::kInvalidArgument);
  // A manifest whose exposures do not divide its images: a format error naming the key.
  info.exposures = {1.0, 0.25};
  { RecordingWriter::create(dir.file("c"), info, std::nullopt).close(); }
  std::string manifest = read_file_text(dir.file("c/manifest.json"));
  const std::size_t at = manifest.find("\"images_per_frame\": 4");
  ASSERT_NE(at, std::string::npos);
  manifest.replace(at, 21, "\"images_per_frame\": 3");
  write_file_atomic(dir.file("c/manifest.json"), manifest);
  try {
    RecordingReader::open(dir.file("c"));
    FAIL() << "accepted";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), ErrorCode::kFormat);
    EXPECT_NE(std::string(error.what()).find("exposures"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace sls::session
