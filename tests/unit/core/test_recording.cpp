// Recordings: write -> read equality, crash safety (an interrupted writer leaves a valid
// recording of the frames it finished), and an sls::Error naming the file for every kind of
// damage (corrupt manifest, missing/truncated/mis-sized image, future version, escaping path).
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "sdk/core/device.h"
#include "sdk/core/error.h"
#include "sdk/core/file_util.h"
#include "sdk/core/image_io.h"
#include "sdk/core/recording.h"
#include "sdk/core/recording_manifest.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

namespace fs = std::filesystem;

constexpr int kWidth = 37;
constexpr int kHeight = 23;
constexpr int kImagesPerFrame = 4;

ScannerCalibration make_calibration() {
  ScannerCalibration c;
  c.camera.width = kWidth;
  c.camera.height = kHeight;
  c.camera.fx = 80.5;
  c.camera.fy = 81.25;
  c.camera.cx = 18.0;
  c.camera.cy = 11.5;
  c.camera.k1 = -0.125;
  c.projector.width = 64;
  c.projector.height = 48;
  c.projector.fx = 120.0;
  c.projector.fy = 120.5;
  c.projector.cx = 32.0;
  c.projector.cy = 24.0;
  c.T_camera_projector =
      Pose(Eigen::Quaterniond(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0.08, 0.0, 0.01));
  c.turntable = TurntableAxis{Eigen::Vector3d(0.0, 0.01, 0.2), Eigen::Vector3d::UnitY()};
  c.reprojection_rms_px = 0.25;
  c.description = "recording test rig";
  return c;
}

RecordingInfo make_info(int bit_depth) {
  RecordingInfo info;
  info.device = {"sim://knurl", "slscan-sim", "SN-0042"};
  info.camera = {kWidth, kHeight, bit_depth};
  info.pattern_set_json = R"({"name": "gray+phase", "image_count": 4, "periods": [16, 32]})";
  info.images_per_frame = kImagesPerFrame;
  return info;
}

template <typename T>
std::vector<Image<T>> random_images(int count, int max_value, std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_int_distribution<int> value(0, max_value);
  std::vector<Image<T>> images;
  for (int k = 0; k < count; ++k) {
    Image<T> image(kWidth, kHeight);
    for (std::size_t i = 0; i < image.pixel_count(); ++i) image.data()[i] = static_cast<T>(value(random));
    images.push_back(std::move(image));
  }
  return images;
}

Image32f random_depth(std::uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> depth(0.001f, 0.065f);
  Image32f image(kWidth, kHeight);
  for (std::size_t i = 0; i < image.pixel_count(); ++i) image.data()[i] = depth(random);
  image(0, 0) = 0.0f;                                       // invalid
  image(1, 0) = std::numeric_limits<float>::quiet_NaN();    // invalid
  image(2, 0) = -0.01f;                                     // invalid
  image(3, 0) = 0.065535f;                                  // the largest storable depth
  return image;
}

FrameMetadata metadata(std::int64_t timestamp_ns, std::optional<double> angle) {
  FrameMetadata m;
  m.timestamp_ns = timestamp_ns;
  m.turntable_angle_deg = angle;
  return m;
}

void expect_calibration_equal(const ScannerCalibration& a, const ScannerCalibration& b) {
  for (auto [x, y] : {std::pair{a.camera, b.camera}, std::pair{a.projector, b.projector}}) {
    EXPECT_EQ(x.width, y.width);
    EXPECT_EQ(x.height, y.height);
    EXPECT_DOUBLE_EQ(x.fx, y.fx);
    EXPECT_DOUBLE_EQ(x.fy, y.fy);
    EXPECT_DOUBLE_EQ(x.cx, y.cx);
    EXPECT_DOUBLE_EQ(x.cy, y.cy);
    EXPECT_DOUBLE_EQ(x.k1, y.k1);
    EXPECT_DOUBLE_EQ(x.k2, y.k2);
    EXPECT_DOUBLE_EQ(x.k3, y.k3);
    EXPECT_DOUBLE_EQ(x.p1, y.p1);
    EXPECT_DOUBLE_EQ(x.p2, y.p2);
  }
  EXPECT_TRUE(a.T_camera_projector.is_approx(b.T_camera_projector, 1e-12));
  ASSERT_EQ(a.turntable.has_value(), b.turntable.has_value());
  if (a.turntable) {
    EXPECT_TRUE(a.turntable->point_camera.isApprox(b.turntable->point_camera));
    EXPECT_TRUE(a.turntable->direction_camera.isApprox(b.turntable->direction_camera));
  }
  EXPECT_DOUBLE_EQ(a.reprojection_rms_px, b.reprojection_rms_px);
  EXPECT_EQ(a.description, b.description);
}

template <typename Call>
void expect_error(Call&& call, ErrorCode code, const std::string& needle) {
  try {
    call();
    ADD_FAILURE() << "no error thrown";
  } catch (const Error& error) {
    EXPECT_EQ(error.code(), code) << error.what();
    EXPECT_NE(std::string(error.what()).find(needle), std::string::npos) << "missing '" << needle << "' in: " << error.what();
  }
}

void replace_in_file(const std::string& path, const std::string& from, const std::string& to) {
  std::string text = read_file_text(path);
  const std::size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  write_file_atomic(path, text);
}

void truncate_file(const std::string& path, std::size_t keep) {
  const std::string text = read_file_text(path);
  write_file_atomic(path, text.substr(0, keep));
}

// A 16-bit recording of 3 frames x 4 images in `folder`.
void write_standard_recording(const std::string& folder) {
  RecordingWriter writer = RecordingWriter::create(folder, make_info(12), make_calibration());
  for (int f = 0; f < 3; ++f) {
    const Image32f depth = random_depth(100u + static_cast<std::uint32_t>(f));
    writer.append_frame(random_images<std::uint16_t>(kImagesPerFrame, 4095, static_cast<std::uint32_t>(f)),
                        metadata(1000 + f, 10.0 * f), &depth);
  }
  writer.close();
}

// A recording of one frame of random images of `bits` bits in `folder`; returns the images.
std::vector<Image16u> write_one_frame(const std::string& folder, int bits, std::uint32_t seed) {
  const std::vector<Image16u> images = random_images<std::uint16_t>(kImagesPerFrame, bits == 8 ? 255 : 4095, seed);
  RecordingWriter writer = RecordingWriter::create(folder, make_info(bits), make_calibration());
  writer.append_frame(images, metadata(1, std::nullopt));
  writer.close();
  return images;
}

TEST(Recording, RoundTrip16Bit) {
  test::TemporaryDirectory dir;
  const std::string folder = dir.file("rec");
  const RecordingInfo info = make_info(12);
  std::vector<std::vector<Image16u>> frames;
  std::vector<Image32f> depths;
  const std::vector<std::optional<double>> angles = {0.0, 120.5, std::nullopt};
  const std::vector<std::int64_t> timestamps = {0, 1'700'000'000'123'456'789, -5};
  RecordingWriter writer = RecordingWriter::create(folder, info, make_calibration());
  for (int f = 0; f < 3; ++f) {
    frames.push_back(random_images<std::uint16_t>(kImagesPerFrame, 4095, 10u + static_cast<std::uint32_t>(f)));
    depths.push_back(random_depth(20u + static_cast<std::uint32_t>(f)));
    const bool with_depth = f != 1;
    EXPECT_EQ(writer.append_frame(frames.back(), metadata(timestamps[static_cast<std::size_t>(f)], angles[static_cast<std::size_t>(f)]),
                                  with_depth ? &depths.back() : nullptr),
              f);
  }
  EXPECT_EQ(writer.frame_count(), 3u);
  writer.close();
  expect_error([&] { writer.append_frame(frames[0], metadata(0, std::nullopt)); }, ErrorCode::kInvalidArgument,
               "close");

  const RecordingReader reader = RecordingReader::open(folder);
  EXPECT_EQ(reader.info().device.uri, "sim://knurl");
  EXPECT_EQ(reader.info().device.model, "slscan-sim");
  EXPECT_EQ(reader.info().device.serial, "SN-0042");
  EXPECT_EQ(reader.info().camera.width, kWidth);
  EXPECT_EQ(reader.info().camera.height, kHeight);
  EXPECT_EQ(reader.info().camera.bit_depth, 12);
  EXPECT_EQ(reader.info().images_per_frame, kImagesPerFrame);
  EXPECT_EQ(reader.info().pattern_set_json, writer.info().pattern_set_json);
  EXPECT_EQ(reader.info().pattern_set_json, R"({"name":"gray+phase","image_count":4,"periods":[16,32]})");
  EXPECT_EQ(reader.info().created_utc, writer.info().created_utc);
  EXPECT_EQ(reader.info().created_utc.size(), 20u);
  EXPECT_FALSE(reader.info().has_groundtruth);
  EXPECT_EQ(reader.groundtruth_folder(), "");
  ASSERT_TRUE(reader.has_calibration());
  expect_calibration_equal(reader.calibration(), make_calibration());

  ASSERT_EQ(reader.frame_count(), 3u);
  for (std::size_t f = 0; f < 3; ++f) {
    const FrameInfo& frame = reader.frame(f);
    EXPECT_EQ(frame.index, static_cast<int>(f));
    EXPECT_EQ(frame.timestamp_ns, timestamps[f]);
    EXPECT_EQ(frame.turntable_angle_deg, angles[f]);
    EXPECT_TRUE(frame.complete);
    ASSERT_EQ(frame.image_files.size(), 4u);
    EXPECT_EQ(frame.image_files[2], "frames/00000" + std::to_string(f) + "/pattern_002.png");
    EXPECT_EQ(read_png_header(reader.file_path(frame.image_files[0])).bit_depth, 16);
    const std::vector<Image16u> images = reader.load_images(f);
    ASSERT_EQ(images.size(), 4u);
    for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(images[k], frames[f][k]) << f << " " << k;
    const std::optional<Image32f> depth = reader.load_depth_m(f);
    ASSERT_EQ(depth.has_value(), f != 1);
    if (!depth) continue;
    for (int y = 0; y < kHeight; ++y) {
      for (int x = 0; x < kWidth; ++x) {
        const float written = depths[f](x, y);
        const float read = (*depth)(x, y);
        if (!(written > 0.0f)) {
          EXPECT_EQ(read, 0.0f);
        } else {
          EXPECT_NEAR(read, written, 0.5e-6 + 1e-8) << x << "," << y;
        }
      }
    }
  }
  EXPECT_NO_THROW(reader.verify(true));
  expect_error([&] { reader.frame(3); }, ErrorCode::kInvalidArgument, "frame 3");
}

TEST(Recording, RoundTrip8Bit) {
  test::TemporaryDirectory dir;
  const std::string folder = dir.file("rec8");
  std::vector<std::vector<Image8u>> frames;
  {
    RecordingWriter writer = RecordingWriter::create(folder, make_info(8), make_calibration());
    for (int f = 0; f < 3; ++f) {
      frames.push_back(random_images<std::uint8_t>(kImagesPerFrame, 255, 30u + static_cast<std::uint32_t>(f)));
      writer.append_frame(frames.back(), metadata(f * 1000, 1.5 * f));
    }
  }
  const RecordingReader reader = RecordingReader::open(folder);
  ASSERT_EQ(reader.frame_count(), 3u);
  EXPECT_EQ(reader.info().camera.bit_depth, 8);
  for (std::size_t f = 0; f < 3; ++f) {
    EXPECT_EQ(reader.frame(f).turntable_angle_deg, 1.5 * static_cast<double>(f));
    EXPECT_FALSE(reader.frame(f).has_depth());
    EXPECT_FALSE(reader.load_depth_m(f).has_value());
    EXPECT_EQ(read_png_header(reader.file_path(reader.frame(f).image_files[0])).bit_depth, 8);
    const std::vector<Image16u> images = reader.load_images(f);
    for (std::size_t k = 0; k < 4; ++k) {
      for (std::size_t i = 0; i < images[k].pixel_count(); ++i) {
        ASSERT_EQ(images[k].data()[i], frames[f][k].data()[i]);  // widened by value
      }
    }
  }
}

// A replay through a GPU session reads its images page-locked (as a camera delivers them), 8-bit
// and 16-bit files alike: the same pixels, in page-locked memory where a GPU can lock it and
// pageable (saying so) where not; a GPU's memory is refused.
TEST(Recording, ImagesLoadIntoTheMemoryAskedFor) {
  test::TemporaryDirectory dir;
  const bool gpu = cuda_compiled() && cuda_device_count() > 0;
  for (const int bits : {8, 16}) {
    const std::string folder = dir.file("rec" + std::to_string(bits));
    const std::vector<Image16u> images = write_one_frame(folder, bits, 9);
    const RecordingReader reader = RecordingReader::open(folder);
    const std::vector<Image16u> pinned = reader.load_images(0, MemoryType::kPinned);
    ASSERT_EQ(pinned.size(), images.size());
    for (std::size_t k = 0; k < images.size(); ++k) {
      EXPECT_EQ(pinned[k], images[k]) << bits << "-bit image " << k;
      EXPECT_EQ(pinned[k].memory_type(), gpu ? MemoryType::kPinned : MemoryType::kHost);
    }
    expect_error([&] { (void)reader.load_image(0, 0, MemoryType::kDevice); }, ErrorCode::kInvalidArgument,
                 "host memory, not a GPU's");
  }
}

// A region of each image (what a calibration reads around its board): the crop of the whole
// image, for 8- and 16-bit recordings; a region outside the camera's image is refused.
TEST(Recording, ARegionOfEachImageIsItsCrop) {
  test::TemporaryDirectory dir;
  for (const int bits : {8, 16}) {
    const std::string folder = dir.file("rec" + std::to_string(bits));
    const std::vector<Image16u> images = write_one_frame(folder, bits, 11);
    const RecordingReader reader = RecordingReader::open(folder);
    const ImageRegion region{3, 5, kWidth - 7, kHeight - 9};
    const std::vector<Image16u> parts = reader.load_images(0, region);
    ASSERT_EQ(parts.size(), images.size());
    for (std::size_t k = 0; k < images.size(); ++k) {
      ASSERT_EQ(parts[k].width(), region.width);
      ASSERT_EQ(parts[k].height(), region.height);
      for (int y = 0; y < region.height; ++y) {
        for (int x = 0; x < region.width; ++x) {
          ASSERT_EQ(parts[k](x, y), images[k](x + region.x0, y + region.y0)) << bits << "-bit image " << k;
        }
      }
    }
    expect_error([&] { (void)reader.load_image(0, 1, ImageRegion{0, 0, kWidth + 1, 4}); }, ErrorCode::kInvalidArgument,
                 "frames/000000/pattern_001.png: the region");
  }
}

TEST(Recording, SixteenBitImagesForAnEightBitCameraAreStoredAs8Bit) {
  test::TemporaryDirectory dir;
  RecordingWriter writer = RecordingWriter::create(dir.file("rec"), make_info(8), make_calibration());
  const std::vector<Image16u> images = random_images<std::uint16_t>(kImagesPerFrame, 255, 5);
  writer.append_frame(images, metadata(1, std::nullopt));
  const RecordingReader reader = RecordingReader::open(dir.file("rec"));
  EXPECT_EQ(read_png_header(reader.file_path(reader.frame(0).image_files[3])).bit_depth, 8);
  EXPECT_EQ(reader.load_images(0), images);
  std::vector<Image16u> too_bright = images;
  too_bright[2](4, 3) = 300;
  expect_error([&] { writer.append_frame(too_bright, metadata(2, std::nullopt)); }, ErrorCode::kInvalidArgument,
               "value 300 at (4, 3)");
}

TEST(Recording, InterruptedRecordingReadsCompletedFrames) {
  test::TemporaryDirectory dir;
  const std::string folder = dir.file("rec");
  std::vector<std::vector<Image16u>> frames;
  {
    RecordingWriter writer = RecordingWriter::create(folder, make_info(16), make_calibration());
    for (int f = 0; f < 2; ++f) {
      frames.push_back(random_images<std::uint16_t>(kImagesPerFrame, 65535, 40u + static_cast<std::uint32_t>(f)));
      writer.append_frame(frames.back(), metadata(f, std::nullopt));
    }
    // The crash: frame 2's first image half written, no manifest entry; no close().
    const std::vector<std::uint8_t> png = encode_png(frames[0][0]);
    create_directories(folder + "/frames/000002");
    std::ofstream stray(folder + "/frames/000002/pattern_000.png", std::ios::binary);
    stray.write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size() / 2));
  }
  const RecordingReader reader = RecordingReader::open(folder);
  ASSERT_EQ(reader.frame_count(), 2u);
  for (std::size_t f = 0; f < 2; ++f) EXPECT_EQ(reader.load_images(f), frames[f]);
  EXPECT_NO_THROW(reader.verify(true));
  // No temporary manifest is left behind either.
  for (const auto& entry : fs::directory_iterator(folder)) {
    EXPECT_EQ(entry.path().filename().string().find(".tmp"), std::string::npos) << entry.path();
  }
}

TEST(Recording, IncompleteFrameKeepsItsImagesAndNote) {
  test::TemporaryDirectory dir;
  RecordingWriter writer = RecordingWriter::create(dir.file("rec"), make_info(16), make_calibration());
  FrameMetadata cut = metadata(7, 45.0);
  cut.complete = false;
  cut.note = "camera timeout after pattern 1";
  const std::vector<Image16u> two = random_images<std::uint16_t>(2, 65535, 50);
  writer.append_frame(two, cut);
  expect_error([&] { writer.append_frame(random_images<std::uint16_t>(5, 1, 1), cut); }, ErrorCode::kInvalidArgument,
               "5 images");
  const RecordingReader reader = RecordingReader::open(dir.file("rec"));
  ASSERT_EQ(reader.frame_count(), 1u);
  EXPECT_FALSE(reader.frame(0).complete);
  EXPECT_EQ(reader.frame(0).note, "camera timeout after pattern 1");
  EXPECT_EQ(reader.load_images(0), two);
}

// A device capture's per-frame counters (the capture sequencer's): kept per frame, absent where
// none were given, and still there after a resumed writer rewrote the manifest.
TEST(Recording, CaptureCountersRoundTripAndSurviveAResume) {
  test::TemporaryDirectory dir;
  const std::string folder = dir.file("rec");
  FrameCaptureCounters sequencer_only;  // a camera whose transport counts nothing (the simulator)
  sequencer_only.attempts = 3;
  sequencer_only.incomplete_images = 1;
  sequencer_only.lost_images = 2;
  sequencer_only.stale_images = 1;
  FrameCaptureCounters gige;  // a GigE Vision camera's
  gige.attempts = 2;
  gige.incomplete_images = 1;
  gige.transport = FrameTransportCounters{5, 7, 2};
  FrameCaptureCounters huge = gige;  // the largest counts the manifest holds
  huge.attempts = std::numeric_limits<int>::max();
  huge.transport->resent_packets = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  const std::vector<std::optional<FrameCaptureCounters>> written = {std::nullopt, sequencer_only, gige, huge};
  {
    RecordingWriter writer = RecordingWriter::create(folder, make_info(16), make_calibration());
    for (std::size_t f = 0; f < 3; ++f) {
      FrameMetadata m = metadata(static_cast<std::int64_t>(f), std::nullopt);
      m.capture = written[f];
      writer.append_frame(random_images<std::uint16_t>(kImagesPerFrame, 65535, 60u + static_cast<std::uint32_t>(f)), m);
      EXPECT_EQ(writer.frame(f).capture, written[f]) << "frame " << f;
    }
  }
  const std::string text = read_file_text(folder + "/manifest.json");
  const auto count = [&text](const std::string& key) {
    std::size_t n = 0;
    for (std::size_t at = text.find(key); at != std::string::npos; at = text.find(key, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("\"capture\""), 2u) << "frame 0 has no capture key: " << text;
  EXPECT_EQ(count("\"resent_packets\""), 1u) << "only frame 2 has transport counters";
  {
    RecordingWriter resumed = RecordingWriter::append_to(folder);
    FrameMetadata m = metadata(3, std::nullopt);
    m.capture = huge;
    resumed.append_frame(random_images<std::uint16_t>(kImagesPerFrame, 65535, 63), m);
  }
  const RecordingReader reader = RecordingReader::open(folder);
  ASSERT_EQ(reader.frame_count(), written.size());
  for (std::size_t f = 0; f < written.size(); ++f) EXPECT_EQ(reader.frame(f).capture, written[f]) << "frame " << f;
  EXPECT_FALSE(reader.frame(1).capture->transport.has_value());

  // The writer refuses what the reader would refuse.
  RecordingWriter writer = RecordingWriter::create(dir.file("bad"), make_info(16), make_calibration());
  for (const auto& spoil : std::vector<void (*)(FrameCaptureCounters&)>{
           [](FrameCaptureCounters& c) { c.attempts = 0; }, [](FrameCaptureCounters& c) { c.lost_images = -1; },
           [](FrameCaptureCounters& c) { c.transport->missing_packets = ~std::uint64_t{0}; }}) {
    FrameMetadata m = metadata(0, std::nullopt);
    m.capture = gige;
    spoil(*m.capture);
    expect_error([&] { writer.append_frame(random_images<std::uint16_t>(kImagesPerFrame, 1, 1), m); },
                 ErrorCode::kInvalidArgument, "capture counters out of range");
  }
  EXPECT_EQ(writer.frame_count(), 0u);
}

TEST(Recording, GroundtruthFolderAndNoCalibration) {
  test::TemporaryDirectory dir;
  RecordingInfo info = make_info(16);
  info.has_groundtruth = true;
  RecordingWriter writer = RecordingWriter::create(dir.file("sim"), info, std::nullopt);
  EXPECT_TRUE(fs::is_directory(writer.groundtruth_folder()));
  write_file_atomic(writer.groundtruth_folder() + "/poses.txt", "0 0 0 0 0 0 0 1\n");
  const RecordingReader reader = RecordingReader::open(dir.file("sim"));
  EXPECT_TRUE(reader.info().has_groundtruth);
  EXPECT_EQ(reader.groundtruth_folder(), writer.groundtruth_folder());
  EXPECT_FALSE(reader.has_calibration());
  expect_error([&] { reader.calibration(); }, ErrorCode::kNotFound, "without calibration");
  EXPECT_EQ(reader.frame_count(), 0u);
}

TEST(Recording, DepthOffsetExtendsTheRange) {
  test::TemporaryDirectory dir;
  RecordingInfo info = make_info(16);
  info.depth_offset_m = 0.25;  // a 250 mm stand-off
  RecordingWriter writer = RecordingWriter::create(dir.file("rec"), info, make_calibration());
  Image32f depth(kWidth, kHeight, 0.2734567f);
  depth(0, 0) = 0.2f;    // below the offset: stored invalid
  depth(1, 0) = 0.32f;   // beyond offset + 65.535 mm: stored invalid, not clamped
  writer.append_frame(random_images<std::uint16_t>(kImagesPerFrame, 10, 1), metadata(0, std::nullopt), &depth);
  const RecordingReader reader = RecordingReader::open(dir.file("rec"));
  EXPECT_DOUBLE_EQ(reader.info().depth_offset_m, 0.25);
  const Image32f read = *reader.load_depth_m(0);
  EXPECT_EQ(read(0, 0), 0.0f);
  EXPECT_EQ(read(1, 0), 0.0f);
  EXPECT_NEAR(read(2, 0), 0.2734567f, 0.5e-6 + 3e-8);
}

TEST(Recording, DepthOnlyRecordingRoundTripsAndNeedsDepthMaps) {
  test::TemporaryDirectory dir;
  RecordingInfo info = make_info(16);
  info.images_per_frame = 0;
  info.depth_offset_m = 0.07;
  RecordingWriter writer = RecordingWriter::create(dir.file("rec"), info, make_calibration());
  Image32f depth(kWidth, kHeight, 0.1001234f);
  depth(3, 2) = 0.0f;  // invalid stays invalid
  writer.append_frame(std::vector<Image16u>{}, metadata(0, 12.5), &depth);
  expect_error([&] { writer.append_frame(std::vector<Image16u>{}, metadata(1, 13.0)); }, ErrorCode::kInvalidArgument,
               "depth map");
  writer.close();
  const RecordingReader reader = RecordingReader::open(dir.file("rec"));
  EXPECT_EQ(reader.info().images_per_frame, 0);
  ASSERT_EQ(reader.frame_count(), 1u);
  EXPECT_TRUE(reader.load_images(0).empty());
  const Image32f read = *reader.load_depth_m(0);
  EXPECT_NEAR(read(0, 0), 0.1001234f, 0.5e-6 + 3e-8);
  EXPECT_EQ(read(3, 2), 0.0f);
}

TEST(Recording, WriterRejectsCallerMistakes) {
  test::TemporaryDirectory dir;
  // A non-empty folder.
  create_directories(dir.file("busy"));
  write_file_atomic(dir.file("busy/file.txt"), "x");
  expect_error([&] { RecordingWriter::create(dir.file("busy"), make_info(16), make_calibration()); },
               ErrorCode::kInvalidArgument, "not empty");
  // Bad info.
  RecordingInfo info = make_info(16);
  info.pattern_set_json = "[1, 2]";
  expect_error([&] { RecordingWriter::create(dir.file("a"), info, make_calibration()); }, ErrorCode::kInvalidArgument,
               "object");
  EXPECT_FALSE(fs::exists(dir.file("a")));  // a refused create leaves nothing behind
  info.pattern_set_json = "{\"name\": ";
  expect_error([&] { RecordingWriter::create(dir.file("b"), info, make_calibration()); }, ErrorCode::kInvalidArgument,
               "not valid JSON");
  info = make_info(17);
  expect_error([&] { RecordingWriter::create(dir.file("c"), info, make_calibration()); }, ErrorCode::kInvalidArgument,
               "bit depth");
  ScannerCalibration other = make_calibration();
  other.camera.width = 40;
  other.camera.cx = 20.0;
  expect_error([&] { RecordingWriter::create(dir.file("d"), make_info(16), other); }, ErrorCode::kInvalidArgument,
               "40x23");
  // Bad frames.
  RecordingWriter writer = RecordingWriter::create(dir.file("e"), make_info(12), make_calibration());
  expect_error([&] { writer.append_frame(random_images<std::uint16_t>(3, 1, 1), metadata(0, std::nullopt)); },
               ErrorCode::kInvalidArgument, "3 images");
  std::vector<Image16u> images = random_images<std::uint16_t>(4, 1, 1);
  images[1] = Image16u(kWidth + 1, kHeight);
  expect_error([&] { writer.append_frame(images, metadata(0, std::nullopt)); }, ErrorCode::kInvalidArgument,
               "image 1 is 38x23");
  images[1] = Image16u(kWidth, kHeight, 4096);
  expect_error([&] { writer.append_frame(images, metadata(0, std::nullopt)); }, ErrorCode::kInvalidArgument,
               "12-bit");
  expect_error([&] { writer.append_frame(random_images<std::uint8_t>(4, 1, 1), metadata(0, std::nullopt)); },
               ErrorCode::kInvalidArgument, "8-bit images");
  const Image32f small_depth(3, 3);
  expect_error(
      [&] { writer.append_frame(random_images<std::uint16_t>(4, 1, 1), metadata(0, std::nullopt), &small_depth); },
      ErrorCode::kInvalidArgument, "depth map");
  expect_error([&] { writer.append_frame(random_images<std::uint16_t>(4, 1, 1), metadata(0, std::nan(""))); },
               ErrorCode::kInvalidArgument, "angle");
  // None of that was recorded; the next good frame is frame 0.
  EXPECT_EQ(writer.append_frame(random_images<std::uint16_t>(4, 1, 1), metadata(0, std::nullopt)), 0);
  EXPECT_EQ(RecordingReader::open(dir.file("e")).frame_count(), 1u);
}

TEST(Recording, FailedAppendLeavesTheRecordingValid) {
  test::TemporaryDirectory dir;
  const std::string folder = dir.file("rec");
  RecordingWriterOptions options;
  options.encode_threads = 3;  // the failure happens on a worker thread
  RecordingWriter writer = RecordingWriter::create(folder, make_info(16), make_calibration(), options);
  const std::vector<Image16u> images = random_images<std::uint16_t>(kImagesPerFrame, 65535, 60);
  const Image32f depth = random_depth(61);
  writer.append_frame(images, metadata(0, std::nullopt), &depth);
  // A directory where frame 1's third image should go: that write fails.
  create_directories(folder + "/frames/000001/pattern_002.png");
  expect_error([&] { writer.append_frame(images, metadata(1, std::nullopt), &depth); }, ErrorCode::kIo,
               "frames/000001/pattern_002.png");
  EXPECT_EQ(writer.frame_count(), 1u);
  EXPECT_EQ(RecordingReader::open(folder).frame_count(), 1u);
  fs::remove(folder + "/frames/000001/pattern_002.png");
  EXPECT_EQ(writer.append_frame(images, metadata(2, std::nullopt), &depth), 1);
  const RecordingReader reader = RecordingReader::open(folder);
  ASSERT_EQ(reader.frame_count(), 2u);
  EXPECT_EQ(reader.frame(1).timestamp_ns, 2);
  EXPECT_EQ(reader.load_images(1), images);
}

// --- Damaged recordings: each an sls::Error naming the file.

class DamagedRecording : public ::testing::Test {
 protected:
  void SetUp() override { write_standard_recording(folder); }
  std::string file(const std::string& relative) const { return folder + "/" + relative; }

  test::TemporaryDirectory dir;
  std::string folder = dir.file("rec");
};

TEST_F(DamagedRecording, CorruptManifestReportsTheBytePosition) {
  truncate_file(file("manifest.json"), 200);
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "manifest.json");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "at byte 201 (the file ends at byte 200: truncated?)");
  write_file_atomic(file("manifest.json"), "");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "manifest.json");
}

TEST_F(DamagedRecording, MissingManifestOrFolderIsNotFound) {
  expect_error([&] { RecordingReader::open(dir.file("nothing")); }, ErrorCode::kNotFound, "nothing");
  fs::remove(file("manifest.json"));
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kNotFound, "manifest.json");
}

TEST_F(DamagedRecording, MissingCalibrationIsNotFound) {
  fs::remove(file("calibration.yml"));
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kNotFound, "calibration.yml");
}

TEST_F(DamagedRecording, MissingImageNamesTheFile) {
  fs::remove(file("frames/000001/pattern_002.png"));
  const RecordingReader reader = RecordingReader::open(folder);
  EXPECT_NO_THROW(reader.load_images(0));
  expect_error([&] { reader.load_images(1); }, ErrorCode::kNotFound, "frames/000001/pattern_002.png");
  expect_error([&] { reader.verify(); }, ErrorCode::kNotFound, "frames/000001/pattern_002.png");
}

TEST_F(DamagedRecording, TruncatedImageNamesTheFile) {
  const std::string png = file("frames/000002/pattern_001.png");
  truncate_file(png, read_file_bytes(png).size() / 2);
  const RecordingReader reader = RecordingReader::open(folder);
  expect_error([&] { reader.load_images(2); }, ErrorCode::kFormat, "frames/000002/pattern_001.png");
  expect_error([&] { reader.load_images(2, ImageRegion{0, 0, 4, 4}); }, ErrorCode::kFormat,
               "frames/000002/pattern_001.png");
  expect_error([&] { reader.verify(true); }, ErrorCode::kFormat, "frames/000002/pattern_001.png");
  truncate_file(file("frames/000000/depth.png"), 40);
  expect_error([&] { reader.load_depth_m(0); }, ErrorCode::kFormat, "frames/000000/depth.png");
}

TEST_F(DamagedRecording, WrongSizeImageNamesTheFile) {
  write_png(file("frames/000001/pattern_000.png"), Image16u(kWidth, kHeight + 1));
  const RecordingReader reader = RecordingReader::open(folder);
  expect_error([&] { reader.load_images(1); }, ErrorCode::kFormat, "frames/000001/pattern_000.png: image is 37x24");
  expect_error([&] { reader.load_images(1, ImageRegion{0, 0, 4, 4}); }, ErrorCode::kFormat,
               "frames/000001/pattern_000.png: image is 37x24");
  expect_error([&] { reader.verify(); }, ErrorCode::kFormat, "frames/000001/pattern_000.png");
  write_png(file("frames/000002/depth.png"), Image8u(kWidth, kHeight));
  expect_error([&] { reader.load_depth_m(2); }, ErrorCode::kFormat, "depth.png");
}

TEST_F(DamagedRecording, FutureVersionIsAVersionMismatch) {
  replace_in_file(file("manifest.json"), "\"format_version\": 1", "\"format_version\": 3");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kVersionMismatch, "manifest.json");
}

TEST_F(DamagedRecording, ForeignFormatIsRejected) {
  replace_in_file(file("manifest.json"), "\"slscan-recording\"", "\"something-else\"");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "something-else");
}

TEST_F(DamagedRecording, PathsMustStayInsideTheFolder) {
  replace_in_file(file("manifest.json"), "\"frames/000001/pattern_003.png\"", "\"../outside.png\"");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "frames[1].images[3]");
  replace_in_file(file("manifest.json"), "\"../outside.png\"", "\"frames/../../outside.png\"");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "leaves the recording folder");
  replace_in_file(file("manifest.json"), "\"frames/../../outside.png\"", "\"/etc/passwd\"");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "absolute");
}

TEST_F(DamagedRecording, MistypedOrMissingKeysNameTheKey) {
  const std::string manifest = read_file_text(file("manifest.json"));
  replace_in_file(file("manifest.json"), "\"timestamp_ns\": 1001", "\"timestamp_ns\": \"1001\"");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "'frames[1].timestamp_ns' must be an integer");
  write_file_atomic(file("manifest.json"), manifest);
  replace_in_file(file("manifest.json"), "\"images_per_frame\": 4", "\"images_per_frame\": 5");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "'frames[0].images' lists 4 images");
  write_file_atomic(file("manifest.json"), manifest);
  replace_in_file(file("manifest.json"), "\"camera\"", "\"kamera\"");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "missing key 'camera'");
  write_file_atomic(file("manifest.json"), manifest);
  replace_in_file(file("manifest.json"), "\"status\": \"complete\"", "\"status\": \"done\"");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "frames[0].status");
  write_file_atomic(file("manifest.json"), manifest);
  EXPECT_NO_THROW(RecordingReader::open(folder));
}

// The optional per-frame "capture" counters: a manifest without them (every recording before
// them, and the simulator's) reads as before; present ones are checked key by key.
TEST_F(DamagedRecording, CaptureCountersAreOptionalButCheckedWhenPresent) {
  const std::string manifest = read_file_text(file("manifest.json"));
  EXPECT_FALSE(RecordingReader::open(folder).frame(1).capture.has_value());
  const auto with_capture = [&](const std::string& counters) {
    write_file_atomic(file("manifest.json"), manifest);
    replace_in_file(file("manifest.json"), "\"timestamp_ns\": 1001", "\"timestamp_ns\": 1001, \"capture\": " + counters);
  };
  with_capture(R"({"attempts": 2, "incomplete_images": 1, "lost_images": 0, "stale_images": 0, "unknown": 1})");
  FrameCaptureCounters expected;
  expected.attempts = 2;
  expected.incomplete_images = 1;
  EXPECT_EQ(RecordingReader::open(folder).frame(1).capture, expected) << "unknown keys are ignored, as elsewhere";
  with_capture("null");
  EXPECT_FALSE(RecordingReader::open(folder).frame(1).capture.has_value());
  const std::pair<const char*, const char*> bad[] = {
      {"[]", "'frames[1].capture' must be an object"},
      {R"({"attempts": 0, "incomplete_images": 0, "lost_images": 0, "stale_images": 0})",
       "'frames[1].capture.attempts' = 0 is outside 1.."},
      {R"({"attempts": 1, "incomplete_images": 0, "lost_images": -1, "stale_images": 0})",
       "'frames[1].capture.lost_images' = -1 is outside 0.."},
      {R"({"attempts": 1, "incomplete_images": 0, "lost_images": 0, "stale_images": "2"})",
       "'frames[1].capture.stale_images' must be an integer"},
      {R"({"attempts": 1, "incomplete_images": 0, "lost_images": 0})", "missing key 'frames[1].capture.stale_images'"},
      {R"({"attempts": 1, "incomplete_images": 0, "lost_images": 0, "stale_images": 0, "resent_packets": 3})",
       "missing key 'frames[1].capture.missing_packets'"},
      {R"({"attempts": 1, "incomplete_images": 0, "lost_images": 0, "stale_images": 0, "resent_packets": 0,
           "missing_packets": 18446744073709551615, "queue_depth": 0})",
       "'frames[1].capture.missing_packets' = 18446744073709551615 is outside 0.."},
      {R"({"attempts": 1, "incomplete_images": 0, "lost_images": 0, "stale_images": 0, "resent_packets": 0,
           "missing_packets": 0, "queue_depth": 1.5})",
       "'frames[1].capture.queue_depth' must be an integer"},
  };
  for (const auto& [counters, message] : bad) {
    with_capture(counters);
    expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, message);
  }
}

// Found by fuzz_recording_manifest: well-formed JSON holding a number beyond a double made
// nlohmann throw out_of_range, which escaped as an internal error.
TEST_F(DamagedRecording, ANumberBeyondADoubleIsAFormatError) {
  replace_in_file(file("manifest.json"), "\"timestamp_ns\": 1001", "\"timestamp_ns\": 1e999");
  expect_error([&] { RecordingReader::open(folder); }, ErrorCode::kFormat, "manifest.json: corrupt manifest");
  // The fuzzer's input, parsed on its own.
  expect_error([&] { parse_recording_manifest("333.057173333330000e0000571>33336\nrmi}", "fuzzed.json"); },
               ErrorCode::kFormat, "fuzzed.json: corrupt manifest");
}

}  // namespace
}  // namespace sls
