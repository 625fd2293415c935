// sls import's library (calib/capture_import.h): captures of other systems into recordings.
//  - Real data: shared/data/procam-calibration imported from its folder with the shipped
//    description of OpenCV's Gray code (samples/patterns/), its calibration XML read by the
//    key mapping; the recording decodes exactly as the interop test's direct decode of the
//    same PNGs with the same calibration (test_procam_decode: the same figures).
//  - Simulated data written as other tools would (BMP, 16-bit TIFF, an OpenCV stereo
//    calibration with K1/D1/K2/D2/R/T in millimetres): the import decodes to the simulator's
//    ground truth, so the field mapping and the R/T convention are right.
//  - The errors: wrong image count, mixed sizes, an unreadable calibration, a description
//    that does not match the images.
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "calib/capture_import.h"
#include "drivers/sim/renderer.h"
#include "drivers/sim/rig.h"
#include "sdk/core/error.h"
#include "sdk/core/image_io.h"
#include "sdk/core/recording.h"
#include "sdk/decode/decoder.h"
#include "sdk/decode/pattern_families.h"
#include "tests/support/test_support.h"

namespace sls {
namespace {

namespace fs = std::filesystem;

std::string sample(const std::string& name) { return std::string(SLS_SOURCE_DIR) + "/samples/patterns/" + name; }

ErrorCode import_error(const calib::CaptureImportOptions& options, std::string* message = nullptr) {
  try {
    calib::import_capture(options);
  } catch (const Error& error) {
    if (message != nullptr) *message = error.what();
    return error.code();
  }
  return ErrorCode::kInternal;  // no error
}

// The interop test's options for these 8-bit captures (test_procam_decode.cpp).
DecodeOptions procam_options() {
  DecodeOptions options;
  options.bit_depth = 8;
  options.black_level_dn = 0.0;
  options.gain_e_per_dn = 40.0;
  options.read_noise_dn = 0.5;
  options.min_depth_m = 1e-4;
  options.max_depth_m = 1e6;
  options.max_epipolar_error_px = 1e9;
  return options;
}

TEST(CaptureImport, ProcamCalibrationFolderDecodesAsTheInteropTest) {
  const test::TemporaryDirectory temp;
  calib::CaptureImportOptions options;
  options.images = test::shared_data_path("procam-calibration");
  options.patterns = load_pattern_description(sample("opencv_graycode_1024x768.json"));
  options.calibration = test::shared_data_path("procam-calibration/calibration_result.xml");
  options.out = temp.file("procam");
  const calib::CaptureImportSummary summary = calib::import_capture(options);
  EXPECT_EQ(summary.frames, 5);
  EXPECT_EQ(summary.bit_depth, 8);
  ASSERT_EQ(summary.skipped.size(), 1u);  // graycode_pattern/: the projected patterns themselves
  EXPECT_NE(summary.skipped[0].find("graycode_pattern"), std::string::npos);
  EXPECT_EQ(summary.calibration_layout, "cam_int/cam_dist/proj_int/proj_dist/roration/translation");

  const RecordingReader recording = RecordingReader::open(options.out);
  ASSERT_EQ(recording.frame_count(), 5u);
  const ScannerCalibration& c = recording.calibration();
  // The interop test's reading of the same file (OpenCV's stereo convention, T in mm).
  cv::FileStorage file(options.calibration, cv::FileStorage::READ);
  cv::Mat k, d, r, t;
  file["proj_int"] >> k;
  file["cam_dist"] >> d;
  file["roration"] >> r;
  file["translation"] >> t;
  EXPECT_EQ(c.projector.fx, k.at<double>(0, 0));
  EXPECT_EQ(c.projector.cy, k.at<double>(1, 2));
  EXPECT_EQ(c.camera.k3, d.at<double>(4));
  EXPECT_EQ(c.projector.width, 1024);
  EXPECT_EQ(c.camera.width, 1280);
  const Pose T_projector_camera = c.T_camera_projector.inverse();
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(T_projector_camera.translation()[i], 1e-3 * t.at<double>(i), 1e-12);
    for (int j = 0; j < 3; ++j) EXPECT_NEAR(T_projector_camera.rotation()(i, j), r.at<double>(i, j), 1e-9);
  }

  const PatternSet set = pattern_set_from_json(recording.info().pattern_set_json);
  EXPECT_EQ(set.patterns, make_opencv_graycode_pattern_set(1024, 768).patterns);
  Decoder imported(set, c, Device::cpu(), procam_options());
  Decoder direct(make_opencv_graycode_pattern_set(1024, 768), c, Device::cpu(), procam_options());
  for (int capture = 0; capture < 5; ++capture) {
    std::vector<Image16u> stack;
    for (int image = 0; image < 42; ++image) {
      stack.push_back(read_png_u16(test::shared_data_path("procam-calibration/capture_" + std::to_string(capture) +
                                                          "/graycode_" + (image < 10 ? "0" : "") +
                                                          std::to_string(image) + ".png")));
    }
    const DecodedFrame a = direct.decode(stack);
    const DecodedFrame b = imported.decode(recording.load_images(static_cast<std::size_t>(capture)));
    std::size_t different = 0;
    for (std::size_t i = 0; i < a.mask.pixel_count(); ++i) {
      const bool same_u = a.projector_u.data()[i] == b.projector_u.data()[i] ||
                          (std::isnan(a.projector_u.data()[i]) && std::isnan(b.projector_u.data()[i]));
      const bool same_v = a.projector_v.data()[i] == b.projector_v.data()[i] ||
                          (std::isnan(a.projector_v.data()[i]) && std::isnan(b.projector_v.data()[i]));
      different += a.mask.data()[i] != b.mask.data()[i] || !same_u || !same_v ? 1u : 0u;
    }
    std::printf("[import] procam capture %d: %zu pixels decoded from the recording, %zu differ from the direct "
                "decode\n",
                capture, b.ok_count(), different);
    EXPECT_EQ(different, 0u) << capture;
    EXPECT_GT(b.ok_count(), 100000u) << capture;
  }
}

// A simulated capture written as another tool would: one folder per frame, BMP (8-bit) or
// 16-bit TIFF images, and an OpenCV stereo calibration (K1 D1 K2 D2 R T, millimetres).
struct ForeignCapture {
  sim::SimRig rig;
  std::vector<sim::GroundTruthFrame> truth;
  PatternSet set;
};

ForeignCapture write_foreign_capture(const std::string& folder, const std::string& calibration_path, bool tiff) {
  ForeignCapture c;
  c.set = load_pattern_description(sample("complementary_gray_phase_shift.json"));
  const sim::Scene scene = sim::make_plane_scene();
  sim::RigOptions options;
  options.preset = "ci";
  options.camera_width = 240;
  options.noise = false;
  options.patterns = c.set;
  options.bit_depth = tiff ? 12 : 8;
  c.rig = sim::make_rig(options, scene);
  sim::Renderer renderer(c.rig, scene, Device::cpu());
  for (int frame = 0; frame < 2; ++frame) {
    renderer.set_frame(frame);
    const std::string stack = folder + "/scan_" + std::to_string(frame);
    fs::create_directories(stack);
    for (std::size_t k = 0; k < c.set.size(); ++k) {
      const Image16u image = renderer.render_pattern(static_cast<int>(k));
      cv::Mat m(image.height(), image.width(), tiff ? CV_16U : CV_8U);
      for (int y = 0; y < image.height(); ++y) {
        for (int x = 0; x < image.width(); ++x) {
          if (tiff) {
            m.at<std::uint16_t>(y, x) = image(x, y);
          } else {
            m.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(image(x, y));
          }
        }
      }
      // Names that sort wrongly as text (img_10 before img_2): the import orders by number.
      cv::imwrite(stack + "/img_" + std::to_string(k) + (tiff ? ".tif" : ".bmp"), m);
    }
    c.truth.push_back(renderer.ground_truth());
  }
  const ScannerCalibration exact = c.rig.calibration();
  cv::FileStorage out(calibration_path, cv::FileStorage::WRITE);
  const auto matrix = [](const CameraIntrinsics& i) {
    return cv::Mat((cv::Mat_<double>(3, 3) << i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0));
  };
  const auto distortion = [](const CameraIntrinsics& i) {
    return cv::Mat((cv::Mat_<double>(1, 5) << i.k1, i.k2, i.p1, i.p2, i.k3));
  };
  const Pose T_projector_camera = exact.T_camera_projector.inverse();
  cv::Mat r(3, 3, CV_64F), t(3, 1, CV_64F);
  for (int i = 0; i < 3; ++i) {
    t.at<double>(i) = 1e3 * T_projector_camera.translation()[i];
    for (int j = 0; j < 3; ++j) r.at<double>(i, j) = T_projector_camera.rotation()(i, j);
  }
  out << "imageSize" << cv::Mat((cv::Mat_<double>(1, 2) << exact.camera.width, exact.camera.height));
  out << "K1" << matrix(exact.camera) << "D1" << distortion(exact.camera);
  out << "K2" << matrix(exact.projector) << "D2" << distortion(exact.projector);
  out << "R" << r << "T" << t;
  return c;
}

TEST(CaptureImport, ForeignFormatsDecodeToTheGroundTruth) {
  for (const bool tiff : {false, true}) {
    SCOPED_TRACE(tiff ? "16-bit TIFF, YAML" : "8-bit BMP, XML");
    const test::TemporaryDirectory temp;
    const std::string calibration = temp.file(tiff ? "stereo.yml" : "stereo.xml");
    const ForeignCapture capture = write_foreign_capture(temp.file("captures"), calibration, tiff);
    calib::CaptureImportOptions options;
    options.images = temp.file("captures");
    options.patterns = capture.set;
    options.calibration = calibration;
    options.bit_depth = tiff ? 12 : 0;
    options.out = temp.file("recording");
    const calib::CaptureImportSummary summary = calib::import_capture(options);
    EXPECT_EQ(summary.frames, 2);
    EXPECT_EQ(summary.bit_depth, tiff ? 12 : 8);
    EXPECT_EQ(summary.calibration_layout, "K1/D1/K2/D2/R/T");
    const RecordingReader recording = RecordingReader::open(options.out);
    DecodeOptions decode;
    decode.bit_depth = recording.info().camera.bit_depth;
    decode.min_depth_m = 0.09;
    decode.max_depth_m = 0.11;
    Decoder decoder(pattern_set_from_json(recording.info().pattern_set_json), recording.calibration(), Device::cpu(),
                    decode);
    for (std::size_t frame = 0; frame < 2; ++frame) {
      const DecodedFrame d = decoder.decode(recording.load_images(frame));
      const sim::GroundTruthFrame& truth = capture.truth[frame];
      double sum_u = 0.0, sum_z = 0.0;
      std::size_t n = 0, valid = 0;
      for (int y = 0; y < truth.valid.height(); ++y) {
        for (int x = 0; x < truth.valid.width(); ++x) {
          if (!truth.valid(x, y)) continue;
          ++valid;
          if (d.mask(x, y) != kDecodeOk) continue;
          const double du = d.projector_u(x, y) - truth.projector_u(x, y);
          const double dz = d.depth_m(x, y) - truth.depth_m(x, y);
          sum_u += du * du;
          sum_z += dz * dz;
          ++n;
        }
      }
      const double rms_u = std::sqrt(sum_u / static_cast<double>(n)), rms_z = std::sqrt(sum_z / static_cast<double>(n));
      std::printf("[import] %s frame %zu: valid %.3f, projector RMS %.4f px, depth RMS %.2f um\n",
                  tiff ? "tiff" : "bmp", frame, static_cast<double>(n) / static_cast<double>(valid), rms_u, rms_z * 1e6);
      EXPECT_GT(static_cast<double>(n), 0.95 * static_cast<double>(valid));
      EXPECT_LT(rms_u, 0.05);  // the frames are small (240 px) and the plane turned: blur, not the import
      EXPECT_LT(rms_z, 5e-6);  // the calibration's convention is right: microns, not millimetres off
    }
  }
}

TEST(CaptureImport, ClearErrors) {
  const test::TemporaryDirectory temp;
  const std::string calibration = temp.file("stereo.xml");
  const ForeignCapture capture = write_foreign_capture(temp.file("captures"), calibration, false);
  calib::CaptureImportOptions options;
  options.images = temp.file("captures");
  options.patterns = capture.set;
  options.calibration = calibration;
  options.out = temp.file("recording");
  std::string message;

  // A description of another family: the image count differs.
  EXPECT_EQ(import_error([&] {
              calib::CaptureImportOptions o = options;
              o.patterns = load_pattern_description(sample("slscan_gray_phase.json"));
              return o;
            }(), &message),
            ErrorCode::kInvalidArgument);
  EXPECT_NE(message.find("holds 20 images"), std::string::npos) << message;
  EXPECT_NE(message.find("has 22 patterns"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(options.out));

  // The same count in another order: the images do not behave as it says.
  calib::CaptureImportOptions reordered = options;
  std::swap(reordered.patterns.patterns[2], reordered.patterns.patterns[10]);
  EXPECT_NE(import_error(reordered, &message), ErrorCode::kInternal);
  EXPECT_NE(message.find("does not fit the images"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(options.out));

  // An unreadable calibration, and one without the keys.
  calib::CaptureImportOptions broken = options;
  broken.calibration = temp.file("broken.yml");
  {
    std::FILE* f = std::fopen(broken.calibration.c_str(), "w");
    std::fputs("%YAML:1.0\n---\nK1: [ 1, 2\n", f);
    std::fclose(f);
  }
  EXPECT_EQ(import_error(broken, &message), ErrorCode::kFormat);
  EXPECT_NE(message.find("broken.yml"), std::string::npos) << message;
  {
    cv::FileStorage f(broken.calibration, cv::FileStorage::WRITE);
    f << "something" << 1;
  }
  EXPECT_EQ(import_error(broken, &message), ErrorCode::kFormat);
  EXPECT_NE(message.find("no camera matrix (looked for cam_int"), std::string::npos) << message;
  broken.calibration = temp.file("none.yml");
  EXPECT_EQ(import_error(broken, &message), ErrorCode::kNotFound);

  // A missing image, then one of another size.
  const std::string image = temp.file("captures/scan_1/img_5.bmp");
  const cv::Mat kept = cv::imread(image, cv::IMREAD_UNCHANGED);
  fs::remove(image);
  EXPECT_EQ(import_error(options, &message), ErrorCode::kInvalidArgument);
  EXPECT_NE(message.find("holds 19 images"), std::string::npos) << message;
  cv::imwrite(image, cv::Mat(kept.rows / 2, kept.cols / 2, CV_8U, cv::Scalar(7)));
  EXPECT_EQ(import_error(options, &message), ErrorCode::kInvalidArgument);
  EXPECT_NE(message.find("mixed sizes"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(options.out));  // a half import leaves no recording
  cv::imwrite(image, kept);

  // By name pattern: frame 1 alone.
  calib::CaptureImportOptions named = options;
  named.name_pattern = "scan_1/img_{image}.bmp";
  const calib::CaptureImportSummary summary = calib::import_capture(named);
  EXPECT_EQ(summary.frames, 1);
  EXPECT_EQ(RecordingReader::open(options.out).frame_count(), 1u);

  // Both stacks by one pattern with a wildcard: {frame} and {image} wherever they stand.
  named.name_pattern = "scan_{frame}/*_{image}.bmp";
  named.out = temp.file("both");
  EXPECT_EQ(calib::import_capture(named).frames, 2);
  named.out = temp.file("none");
  named.name_pattern = "scan_{frame}/img_{image}.png";  // no such files
  EXPECT_EQ(import_error(named, &message), ErrorCode::kNotFound);
  named.name_pattern = "scan_{frame}/img.bmp";
  EXPECT_EQ(import_error(named, &message), ErrorCode::kInvalidArgument);
  EXPECT_NE(message.find("no {image}"), std::string::npos) << message;
}

}  // namespace
}  // namespace sls
