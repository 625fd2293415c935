#include "sdk/core/calibration.h"

#include <array>
#include <cmath>
#include <initializer_list>
#include <iterator>
#include <tuple>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <yaml-cpp/yaml.h>

#include "sdk/core/error.h"
#include "sdk/core/file_util.h"

namespace sls {
namespace {

// File keys. Distortion vectors use OpenCV's order k1 k2 p1 p2 k3.
constexpr const char* kVersionKey = "slscan_calibration_version";

constexpr const char* kCameraCountKey = "camera_count";

struct DeviceKeys {
  std::string name;  // "camera" / "projector" / "camera1", for messages
  std::string width;
  std::string height;
  std::string matrix;
  std::string distortion;
};

// `prefix`_width ... as the file names a device: "camera", "projector", "camera1".
DeviceKeys device_keys(const std::string& prefix) {
  return {prefix, prefix + "_width", prefix + "_height", prefix + "_matrix", prefix + "_distortion"};
}
const DeviceKeys& camera_keys() {
  static const DeviceKeys keys = device_keys("camera");
  return keys;
}
const DeviceKeys& projector_keys() {
  static const DeviceKeys keys = device_keys("projector");
  return keys;
}

// Camera K (≥ 1) of a multi-camera head: its keys, its pose's key and its RMS key.
std::string additional_camera_prefix(std::size_t index) { return fmt::format("camera{}", index + 1); }
std::string additional_camera_pose_key(std::size_t index) { return fmt::format("T_camera0_camera{}", index + 1); }
std::string additional_camera_rms_key(std::size_t index) { return fmt::format("camera{}_rms_px", index + 1); }

// ---- validation -----------------------------------------------------------------------------

void validate_intrinsics(const CameraIntrinsics& c, const DeviceKeys& keys) {
  if (c.width <= 0 || c.height <= 0) {
    throw_error(ErrorCode::kInvalidArgument, "{}/{}: {} image size {}x{} is not positive", keys.width, keys.height,
                keys.name, c.width, c.height);
  }
  if (!std::isfinite(c.fx) || !std::isfinite(c.fy) || !(c.fx > 0.0) || !(c.fy > 0.0)) {
    throw_error(ErrorCode::kInvalidArgument, "{}: {} focal length (fx {}, fy {}) must be positive and finite",
                keys.matrix, keys.name, c.fx, c.fy);
  }
  // The field of view a focal length gives: below 0.01° or above 170° across the image it is a
  // unit mix-up (metres for pixels) or garbage, not a lens.
  for (const auto& [axis, focal, size] : {std::tuple<const char*, double, int>{"fx", c.fx, c.width},
                                          std::tuple<const char*, double, int>{"fy", c.fy, c.height}}) {
    const double fov_deg = 2.0 * std::atan(0.5 * static_cast<double>(size) / focal) * 180.0 / M_PI;
    if (!(fov_deg >= 0.01 && fov_deg <= 170.0)) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: {} {} = {:g} px gives a field of view of {:.3g}° across {} px (expected 0.01°..170°)",
                  keys.matrix, keys.name, axis, focal, fov_deg, size);
    }
  }
  // A principal point more than an image size outside the image is a unit or order mix-up,
  // not a lens.
  if (!std::isfinite(c.cx) || !std::isfinite(c.cy) || c.cx < -c.width || c.cx > 2.0 * c.width ||
      c.cy < -c.height || c.cy > 2.0 * c.height) {
    throw_error(ErrorCode::kInvalidArgument, "{}: {} principal point ({}, {}) is far outside the {}x{} image",
                keys.matrix, keys.name, c.cx, c.cy, c.width, c.height);
  }
  const std::array<double, 5> distortion = {c.k1, c.k2, c.p1, c.p2, c.k3};
  for (const double d : distortion) {
    if (!std::isfinite(d)) {
      throw_error(ErrorCode::kInvalidArgument, "{}: {} distortion coefficient {} is not finite", keys.distortion,
                  keys.name, d);
    }
  }
}

bool all_finite(const Eigen::Vector3d& v) { return v.allFinite(); }

// The turntable's optional σ keys: file key, what it is, the field.
struct SigmaKey {
  const char* key;
  const char* what;
  const std::optional<double>& value;
};
std::array<SigmaKey, 2> turntable_sigmas(const TurntableAxis& axis) {
  return {SigmaKey{"turntable_angle_sigma_deg", "angle repeatability", axis.angle_sigma_deg},
          SigmaKey{"turntable_tilt_sigma_deg", "tilt (wobble) about axes across its own", axis.tilt_sigma_deg}};
}

// ---- writing --------------------------------------------------------------------------------

// Shortest text that reads back to the same double; always with a '.' or exponent so both
// cv::FileStorage and YAML see a real, not an integer.
std::string format_real(double value) {
  std::string text = fmt::format("{}", value);
  if (text.find_first_of(".eEn") == std::string::npos) text += '.';
  return text;
}

// A YAML double-quoted scalar, escaped the way both yaml-cpp and cv::FileStorage read back.
std::string quote(const std::string& text) {
  std::string out = "\"";
  for (const char c : text) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
          out += fmt::format("\\x{:02x}", static_cast<unsigned>(static_cast<unsigned char>(c)));
        } else {
          out += c;  // UTF-8 bytes pass through
        }
    }
  }
  out += '"';
  return out;
}

// OpenCV's own layout: three-space indent, data wrapped a few values per line.
void write_matrix(std::string& out, const char* key, int rows, int cols, const double* row_major) {
  auto it = std::back_inserter(out);
  fmt::format_to(it, "{}: !!opencv-matrix\n   rows: {}\n   cols: {}\n   dt: d\n   data: [ ", key, rows, cols);
  const int count = rows * cols;
  for (int i = 0; i < count; ++i) {
    if (i > 0) out += (i % 4 == 0) ? ",\n       " : ", ";
    out += format_real(row_major[i]);
  }
  out += " ]\n";
}

void write_intrinsics(std::string& out, const CameraIntrinsics& c, const DeviceKeys& keys) {
  auto it = std::back_inserter(out);
  fmt::format_to(it, "{}: {}\n{}: {}\n", keys.width, c.width, keys.height, c.height);
  const std::array<double, 9> k = {c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0};
  write_matrix(out, keys.matrix.c_str(), 3, 3, k.data());
  const std::array<double, 5> d = {c.k1, c.k2, c.p1, c.p2, c.k3};
  write_matrix(out, keys.distortion.c_str(), 1, 5, d.data());
}

// ---- reading --------------------------------------------------------------------------------

struct Shape {
  int rows, cols;
};

struct Matrix {
  int rows = 0, cols = 0;
  std::vector<double> data;  // row-major
};

// Reads typed values from the top-level mapping; every error names the file, the key and,
// where yaml-cpp knows it, the line.
class Reader {
 public:
  Reader(const std::string& path, const YAML::Node& root) : path_(path), root_(root) {}

  [[noreturn]] void fail(const std::string& key, const YAML::Node* node, const std::string& problem) const {
    if (node != nullptr && node->IsDefined() && node->Mark().line >= 0) {
      throw_error(ErrorCode::kFormat, "{}:{}: key '{}': {}", path_, node->Mark().line + 1, key, problem);
    }
    throw_error(ErrorCode::kFormat, "{}: key '{}': {}", path_, key, problem);
  }

  bool has(const char* key) const {
    const YAML::Node node = root_[key];
    return node.IsDefined() && !node.IsNull();
  }

  YAML::Node required(const char* key) const {
    const YAML::Node node = root_[key];
    if (!node.IsDefined()) fail(key, nullptr, "missing");
    if (node.IsNull()) fail(key, &node, "has no value");
    return node;
  }

  int read_int(const char* key) const {
    const YAML::Node node = required(key);
    return scalar<int>(key, node, "an integer");
  }

  double read_real(const char* key) const {
    const YAML::Node node = required(key);
    return scalar<double>(key, node, "a number");
  }

  std::string read_string(const char* key) const {
    const YAML::Node node = required(key);
    return scalar<std::string>(key, node, "a string");
  }

  // A !!opencv-matrix of doubles with one of the allowed shapes.
  Matrix read_matrix(const char* key, std::initializer_list<Shape> shapes) const {
    const YAML::Node node = required(key);
    if (!node.IsMap()) fail(key, &node, "expected an !!opencv-matrix (rows, cols, dt, data)");
    Matrix m;
    for (const char* field : {"rows", "cols", "dt", "data"}) {
      if (!node[field].IsDefined()) fail(key, &node, fmt::format("matrix has no '{}'", field));
    }
    m.rows = scalar<int>(key, node["rows"], "an integer row count");
    m.cols = scalar<int>(key, node["cols"], "an integer column count");
    const std::string dt = scalar<std::string>(key, node["dt"], "a type code");
    // Single-channel float or double; both hold the values exactly as doubles.
    if (dt != "d" && dt != "f") {
      fail(key, &node, fmt::format("matrix element type '{}' is not supported (expected 'd')", dt));
    }
    bool shape_ok = false;
    std::string expected;
    for (const Shape& shape : shapes) {
      shape_ok = shape_ok || (shape.rows == m.rows && shape.cols == m.cols);
      expected += fmt::format("{}{}x{}", expected.empty() ? "" : " or ", shape.rows, shape.cols);
    }
    if (!shape_ok) fail(key, &node, fmt::format("expected a {} matrix, found {}x{}", expected, m.rows, m.cols));
    const YAML::Node data = node["data"];
    if (!data.IsSequence()) fail(key, &data, "matrix 'data' is not a sequence");
    const std::size_t count = static_cast<std::size_t>(m.rows) * static_cast<std::size_t>(m.cols);
    if (data.size() != count) {
      fail(key, &data, fmt::format("matrix is {}x{} but 'data' has {} values", m.rows, m.cols, data.size()));
    }
    m.data.reserve(count);
    for (std::size_t i = 0; i < count; ++i) {
      const double value = scalar<double>(key, data[i], fmt::format("a number at data[{}]", i).c_str());
      if (!std::isfinite(value)) fail(key, &node, fmt::format("data[{}] is not finite ({})", i, value));
      m.data.push_back(value);
    }
    return m;
  }

 private:
  template <typename T>
  T scalar(const char* key, const YAML::Node& node, const char* what) const {
    if (!node.IsScalar()) fail(key, &node, fmt::format("expected {}", what));
    try {
      return node.as<T>();
    } catch (const YAML::Exception&) {
      fail(key, &node, fmt::format("expected {}, found '{}'", what, node.Scalar()));
    }
  }

  const std::string& path_;
  const YAML::Node& root_;
};

CameraIntrinsics read_intrinsics(const Reader& reader, const DeviceKeys& keys) {
  CameraIntrinsics c;
  c.width = reader.read_int(keys.width.c_str());
  c.height = reader.read_int(keys.height.c_str());
  const Matrix k = reader.read_matrix(keys.matrix.c_str(), {{3, 3}});
  // The model has no skew: anything but [fx 0 cx; 0 fy cy; 0 0 1] would be silently wrong.
  const double* m = k.data.data();
  if (std::fabs(m[1]) > 1e-9 * std::fabs(m[0]) || m[3] != 0.0 || m[6] != 0.0 || m[7] != 0.0 || m[8] != 1.0) {
    const YAML::Node node = reader.required(keys.matrix.c_str());
    reader.fail(keys.matrix, &node, "expected a camera matrix [fx 0 cx; 0 fy cy; 0 0 1] (skew is not supported)");
  }
  c.fx = m[0];
  c.cx = m[2];
  c.fy = m[4];
  c.cy = m[5];
  const Matrix d = reader.read_matrix(keys.distortion.c_str(), {{1, 5}, {5, 1}, {1, 4}, {4, 1}});
  c.k1 = d.data[0];
  c.k2 = d.data[1];
  c.p1 = d.data[2];
  c.p2 = d.data[3];
  c.k3 = d.data.size() > 4 ? d.data[4] : 0.0;
  return c;
}

Eigen::Vector3d read_vector3(const Reader& reader, const char* key) {
  const Matrix m = reader.read_matrix(key, {{3, 1}, {1, 3}});
  return {m.data[0], m.data[1], m.data[2]};
}

// A 4x4 rigid transform (row-major in the file).
Pose read_pose(const Reader& reader, const char* key) {
  const Matrix t = reader.read_matrix(key, {{4, 4}});
  try {
    return Pose::from_matrix(Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(t.data.data()));
  } catch (const Error& error) {
    const YAML::Node node = reader.required(key);
    reader.fail(key, &node, error.what());
  }
}

// yaml-cpp rejects OpenCV's "%YAML:1.0" directive; turning that line into a comment keeps
// the line numbers of parse errors right.
std::string strip_opencv_directive(std::string text) {
  if (text.rfind("%YAML", 0) == 0) text[0] = '#';
  return text;
}

}  // namespace

void ScannerCalibration::validate() const {
  validate_intrinsics(camera, camera_keys());
  validate_intrinsics(projector, projector_keys());
  if (camera_count() > kMaxCameras) {
    throw_error(ErrorCode::kInvalidArgument, "{}: {} cameras (at most {})", kCameraCountKey, camera_count(),
                kMaxCameras);
  }
  for (std::size_t i = 0; i < additional_cameras.size(); ++i) {
    const AdditionalCamera& extra = additional_cameras[i];
    validate_intrinsics(extra.intrinsics, device_keys(additional_camera_prefix(i)));
    if (!extra.T_camera0_camera.translation().allFinite() || !extra.T_camera0_camera.quaternion().coeffs().allFinite()) {
      throw_error(ErrorCode::kInvalidArgument, "{}: the pose is not finite", additional_camera_pose_key(i));
    }
    if (!std::isfinite(extra.rms_px)) {
      throw_error(ErrorCode::kInvalidArgument, "{}: {} is not finite (use -1 for unknown)",
                  additional_camera_rms_key(i), extra.rms_px);
    }
  }
  if (!T_camera_projector.translation().allFinite() || !T_camera_projector.quaternion().coeffs().allFinite()) {
    throw_error(ErrorCode::kInvalidArgument, "T_camera_projector: the pose is not finite");
  }
  // Triangulation needs a baseline: camera and projector in one place is no calibration.
  if (!(T_camera_projector.translation().norm() >= 1e-6)) {
    throw_error(ErrorCode::kInvalidArgument,
                "T_camera_projector: a baseline of {:g} m (camera and projector must be apart to triangulate)",
                T_camera_projector.translation().norm());
  }
  if (turntable) {
    if (!all_finite(turntable->point_camera)) {
      throw_error(ErrorCode::kInvalidArgument, "turntable_axis_point: not finite");
    }
    const double length = turntable->direction_camera.norm();
    if (!std::isfinite(length) || !(std::fabs(length - 1.0) <= 1e-6)) {
      throw_error(ErrorCode::kInvalidArgument,
                  "turntable_axis_direction: length {} (expected a unit vector; a zero axis has no direction)",
                  length);
    }
    for (const auto& [key, what, value] : turntable_sigmas(*turntable)) {
      if (value && (!std::isfinite(*value) || *value < 0.0 || *value > TurntableAxis::kMaxSigmaDeg)) {
        throw_error(ErrorCode::kInvalidArgument,
                    "{}: {} (expected the table's {} in degrees, finite, 0 .. {}; leave the key out when it is not "
                    "known)",
                    key, *value, what, TurntableAxis::kMaxSigmaDeg);
      }
    }
  }
  const std::pair<const char*, double> rms_values[] = {{"reprojection_rms_px", reprojection_rms_px},
                                                       {"camera_rms_px", camera_rms_px},
                                                       {"projector_rms_px", projector_rms_px}};
  for (const auto& [key, value] : rms_values) {
    if (!std::isfinite(value)) {
      throw_error(ErrorCode::kInvalidArgument, "{}: {} is not finite (use -1 for unknown)", key, value);
    }
  }
}

void write_calibration(const std::string& path, const ScannerCalibration& calibration) {
  try {
    calibration.validate();
  } catch (const Error& error) {
    throw_error(ErrorCode::kInvalidArgument, "not writing calibration {}: {}", path, error.what());
  }
  std::string out = "%YAML:1.0\n---\n";
  auto it = std::back_inserter(out);
  fmt::format_to(it, "{}: {}\n", kVersionKey, ScannerCalibration::kFormatVersion);
  fmt::format_to(it, "description: {}\n", quote(calibration.description));
  write_intrinsics(out, calibration.camera, camera_keys());
  write_intrinsics(out, calibration.projector, projector_keys());
  // Eigen is column-major; the file is row-major.
  const Eigen::Matrix<double, 4, 4, Eigen::RowMajor> t = calibration.T_camera_projector.matrix();
  write_matrix(out, "T_camera_projector", 4, 4, t.data());
  // A one-camera head writes no camera keys beyond camera 0's: the file reads as it always did.
  if (!calibration.additional_cameras.empty()) {
    fmt::format_to(it, "{}: {}\n", kCameraCountKey, calibration.camera_count());
  }
  for (std::size_t i = 0; i < calibration.additional_cameras.size(); ++i) {
    const AdditionalCamera& extra = calibration.additional_cameras[i];
    write_intrinsics(out, extra.intrinsics, device_keys(additional_camera_prefix(i)));
    const Eigen::Matrix<double, 4, 4, Eigen::RowMajor> pose = extra.T_camera0_camera.matrix();
    write_matrix(out, additional_camera_pose_key(i).c_str(), 4, 4, pose.data());
    if (extra.rms_px >= 0.0) fmt::format_to(it, "{}: {}\n", additional_camera_rms_key(i), format_real(extra.rms_px));
  }
  if (calibration.turntable) {
    write_matrix(out, "turntable_axis_point", 3, 1, calibration.turntable->point_camera.data());
    write_matrix(out, "turntable_axis_direction", 3, 1, calibration.turntable->direction_camera.data());
    for (const auto& [key, what, value] : turntable_sigmas(*calibration.turntable)) {
      if (value) fmt::format_to(it, "{}: {}\n", key, format_real(*value));
    }
  }
  fmt::format_to(it, "reprojection_rms_px: {}\n", format_real(calibration.reprojection_rms_px));
  if (calibration.camera_rms_px >= 0.0) fmt::format_to(it, "camera_rms_px: {}\n", format_real(calibration.camera_rms_px));
  if (calibration.projector_rms_px >= 0.0) {
    fmt::format_to(it, "projector_rms_px: {}\n", format_real(calibration.projector_rms_px));
  }
  if (!calibration.calibrated_utc.empty()) fmt::format_to(it, "calibrated_utc: {}\n", quote(calibration.calibrated_utc));
  write_file_atomic(path, out);
}

ScannerCalibration read_calibration(const std::string& path) { return parse_calibration(read_file_text(path), path); }

ScannerCalibration parse_calibration(const std::string& file_text, const std::string& path) {
  const std::string text = strip_opencv_directive(file_text);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::ParserException& error) {
    throw_error(ErrorCode::kFormat, "{}:{}:{}: not valid YAML: {}", path, error.mark.line + 1,
                error.mark.column + 1, error.msg);
  } catch (const YAML::Exception& error) {
    throw_error(ErrorCode::kFormat, "{}: not valid YAML: {}", path, error.what());
  }
  if (!root.IsMap()) {
    throw_error(ErrorCode::kFormat, "{}: not a calibration file (expected a YAML mapping of keys)", path);
  }
  const Reader reader(path, root);

  const int version = reader.read_int(kVersionKey);
  if (version > ScannerCalibration::kFormatVersion) {
    throw_error(ErrorCode::kVersionMismatch,
                "{}: key '{}': calibration format version {} is newer than this SDK reads ({})", path, kVersionKey,
                version, ScannerCalibration::kFormatVersion);
  }
  if (version < 1) {
    const YAML::Node node = reader.required(kVersionKey);
    reader.fail(kVersionKey, &node, fmt::format("version {} is not valid", version));
  }

  ScannerCalibration calibration;
  if (reader.has("description")) calibration.description = reader.read_string("description");
  calibration.camera = read_intrinsics(reader, camera_keys());
  calibration.projector = read_intrinsics(reader, projector_keys());
  calibration.T_camera_projector = read_pose(reader, "T_camera_projector");
  if (reader.has(kCameraCountKey)) {
    const int cameras = reader.read_int(kCameraCountKey);
    if (cameras < 1 || cameras > ScannerCalibration::kMaxCameras) {
      const YAML::Node node = reader.required(kCameraCountKey);
      reader.fail(kCameraCountKey, &node,
                  fmt::format("{} cameras (expected 1 .. {})", cameras, ScannerCalibration::kMaxCameras));
    }
    for (std::size_t i = 0; i + 1 < static_cast<std::size_t>(cameras); ++i) {
      AdditionalCamera extra;
      extra.intrinsics = read_intrinsics(reader, device_keys(additional_camera_prefix(i)));
      extra.T_camera0_camera = read_pose(reader, additional_camera_pose_key(i).c_str());
      const std::string rms_key = additional_camera_rms_key(i);
      if (reader.has(rms_key.c_str())) extra.rms_px = reader.read_real(rms_key.c_str());
      calibration.additional_cameras.push_back(extra);
    }
  }

  const bool has_point = reader.has("turntable_axis_point");
  const bool has_direction = reader.has("turntable_axis_direction");
  if (has_point != has_direction) {
    const char* missing = has_point ? "turntable_axis_direction" : "turntable_axis_point";
    reader.fail(missing, nullptr, "missing (the turntable axis needs both a point and a direction)");
  }
  if (has_point) {
    calibration.turntable = TurntableAxis{read_vector3(reader, "turntable_axis_point"),
                                          read_vector3(reader, "turntable_axis_direction")};
    if (reader.has("turntable_angle_sigma_deg")) {
      calibration.turntable->angle_sigma_deg = reader.read_real("turntable_angle_sigma_deg");
    }
    if (reader.has("turntable_tilt_sigma_deg")) {
      calibration.turntable->tilt_sigma_deg = reader.read_real("turntable_tilt_sigma_deg");
    }
  } else {
    for (const char* key : {"turntable_angle_sigma_deg", "turntable_tilt_sigma_deg"}) {
      if (!reader.has(key)) continue;
      const YAML::Node node = reader.required(key);
      reader.fail(key, &node, "given without a turntable axis (turntable_axis_point and turntable_axis_direction)");
    }
  }
  if (reader.has("reprojection_rms_px")) calibration.reprojection_rms_px = reader.read_real("reprojection_rms_px");
  if (reader.has("camera_rms_px")) calibration.camera_rms_px = reader.read_real("camera_rms_px");
  if (reader.has("projector_rms_px")) calibration.projector_rms_px = reader.read_real("projector_rms_px");
  if (reader.has("calibrated_utc")) calibration.calibrated_utc = reader.read_string("calibrated_utc");

  try {
    calibration.validate();
  } catch (const Error& error) {
    throw_error(ErrorCode::kFormat, "{}: invalid calibration: {}", path, error.what());
  }
  return calibration;
}

}  // namespace sls
