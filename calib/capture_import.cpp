#include "calib/capture_import.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <map>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "sdk/core/error.h"
#include "sdk/core/recording.h"
#include "sdk/decode/decoder.h"

namespace sls::calib {
namespace {

namespace fs = std::filesystem;

bool is_image_file(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".png" || ext == ".bmp" || ext == ".tif" || ext == ".tiff";
}

// Name order with digit runs compared as numbers ("img2" before "img10"), as file browsers do.
bool natural_less(const std::string& a, const std::string& b) {
  std::size_t i = 0, j = 0;
  while (i < a.size() && j < b.size()) {
    if (std::isdigit(static_cast<unsigned char>(a[i])) && std::isdigit(static_cast<unsigned char>(b[j]))) {
      std::size_t i_end = i, j_end = j;
      while (i_end < a.size() && std::isdigit(static_cast<unsigned char>(a[i_end]))) ++i_end;
      while (j_end < b.size() && std::isdigit(static_cast<unsigned char>(b[j_end]))) ++j_end;
      const std::string x = a.substr(i, i_end - i), y = b.substr(j, j_end - j);
      const std::string x_trim = x.substr(std::min(x.find_first_not_of('0'), x.size()));
      const std::string y_trim = y.substr(std::min(y.find_first_not_of('0'), y.size()));
      if (x_trim.size() != y_trim.size()) return x_trim.size() < y_trim.size();
      if (x_trim != y_trim) return x_trim < y_trim;
      i = i_end;
      j = j_end;
      continue;
    }
    if (a[i] != b[j]) return a[i] < b[j];
    ++i;
    ++j;
  }
  return a.size() - i < b.size() - j;
}

std::vector<fs::path> entries(const fs::path& folder, bool directories) {
  std::vector<fs::path> out;
  std::error_code error;
  for (const fs::directory_entry& entry : fs::directory_iterator(folder, error)) {
    if (directories ? entry.is_directory() : (entry.is_regular_file() && is_image_file(entry.path()))) {
      out.push_back(entry.path());
    }
  }
  if (error) throw_error(ErrorCode::kIo, "{}: cannot list: {}", folder.string(), error.message());
  std::sort(out.begin(), out.end(),
            [](const fs::path& a, const fs::path& b) { return natural_less(a.filename().string(), b.filename().string()); });
  return out;
}

// A --name-pattern: literal characters, `*` (any run of characters but '/'), `{frame}` and
// `{image}` (a run of digits each). Matched by hand rather than with std::regex: the grammar is
// this small, and libstdc++'s regex trips GCC 12's maybe-uninitialized warning under ASan.
void check_name_pattern(const std::string& pattern) {
  if (pattern.find("{image}") == std::string::npos) {
    throw_error(ErrorCode::kInvalidArgument, "name pattern '{}' has no {{image}} (the image's place in its stack)",
                pattern);
  }
}

// Whether name[n..] matches pattern[p..]; the digits of {frame} and {image} go to *frame / *image.
bool match_name(const std::string& pattern, std::size_t p, const std::string& name, std::size_t n, long long* frame,
                long long* image) {
  if (p == pattern.size()) return n == name.size();
  for (const char* field : {"{frame}", "{image}"}) {
    if (pattern.compare(p, 7, field) != 0) continue;
    std::size_t end = n;
    while (end < name.size() && std::isdigit(static_cast<unsigned char>(name[end])) && end - n < 18) ++end;
    for (; end > n; --end) {  // longest run first, shorter ones if the rest does not match
      if (match_name(pattern, p + 7, name, end, frame, image)) {
        *(field[1] == 'f' ? frame : image) = std::stoll(name.substr(n, end - n));
        return true;
      }
    }
    return false;
  }
  if (pattern[p] == '*') {
    for (std::size_t end = n;; ++end) {
      if (match_name(pattern, p + 1, name, end, frame, image)) return true;
      if (end == name.size() || name[end] == '/') return false;
    }
  }
  return n < name.size() && name[n] == pattern[p] && match_name(pattern, p + 1, name, n + 1, frame, image);
}

void collect(const fs::path& root, const fs::path& folder, std::vector<std::string>* relative) {
  std::error_code error;
  for (const fs::directory_entry& entry : fs::recursive_directory_iterator(folder, error)) {
    if (entry.is_regular_file() && is_image_file(entry.path())) {
      relative->push_back(fs::relative(entry.path(), root).generic_string());
    }
  }
  if (error) throw_error(ErrorCode::kIo, "{}: cannot list: {}", folder.string(), error.message());
}

// One image as 16-bit samples (8-bit images keep their values); *depth: 8 or 16.
Image16u read_image(const std::string& path, int* depth) {
  cv::Mat m;
  try {
    m = cv::imread(path, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& error) {
    throw_error(ErrorCode::kFormat, "{}: cannot read the image: {}", path, error.what());
  }
  if (m.empty()) throw_error(ErrorCode::kFormat, "{}: cannot read the image (corrupt or not PNG/BMP/TIFF)", path);
  if (m.depth() != CV_8U && m.depth() != CV_16U) {
    throw_error(ErrorCode::kFormat, "{}: {}-byte samples; 8 or 16-bit integer images only", path, m.elemSize1());
  }
  if (m.channels() == 3 || m.channels() == 4) {
    cv::Mat grey;  // grey images saved as colour (equal channels) stay exact
    cv::cvtColor(m, grey, m.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
    m = grey;
  } else if (m.channels() != 1) {
    throw_error(ErrorCode::kFormat, "{}: {} channels; grey or colour images only", path, m.channels());
  }
  *depth = m.depth() == CV_8U ? 8 : 16;
  Image16u image(m.cols, m.rows);
  for (int y = 0; y < m.rows; ++y) {
    for (int x = 0; x < m.cols; ++x) {
      image(x, y) = m.depth() == CV_8U ? m.at<std::uint8_t>(y, x) : m.at<std::uint16_t>(y, x);
    }
  }
  return image;
}

// Decodes the first stack with thresholds for an unknown camera of that bit depth and
// depth/epipolar tests off (a calibration may be approximate): what this checks is that the
// images behave as the description says (the decoder's stack check) and that they decode.
double check_description(const CaptureImportOptions& options, const ScannerCalibration& calibration,
                         const std::vector<Image16u>& stack, int bit_depth, const std::string& where) {
  DecodeOptions decode;
  decode.bit_depth = bit_depth;
  // The default rig's sensor behind an ADC of this depth (an unknown camera's noise model: at
  // 8 bits the defaults' 2.6 e-/DN would call every fringe noise).
  decode.gain_e_per_dn = DecodeOptions{}.gain_e_per_dn * std::ldexp(1.0, 12 - bit_depth);
  decode.read_noise_dn = std::max(0.5, DecodeOptions{}.read_noise_dn * std::ldexp(1.0, bit_depth - 12));
  decode.black_level_dn = 0.0;
  decode.min_depth_m = 1e-6;
  decode.max_depth_m = 1e6;
  decode.max_epipolar_error_px = 1e9;
  try {
    Decoder decoder(options.patterns, calibration, Device::cpu(), decode);
    const DecodedFrame frame = decoder.decode(stack);
    std::size_t coordinates = 0;
    for (std::size_t i = 0; i < frame.mask.pixel_count(); ++i) {
      const std::uint8_t m = frame.mask.data()[i];
      coordinates += m == kDecodeOk || m == kDecodeOutOfRange ? 1u : 0u;
    }
    const double fraction = static_cast<double>(coordinates) / static_cast<double>(frame.mask.pixel_count());
    if (coordinates == 0) {
      throw_error(ErrorCode::kFormat, "no pixel decodes: is the description's image order the capture's?");
    }
    return fraction;
  } catch (const Error& error) {
    throw_error(error.code() == ErrorCode::kFormat ? ErrorCode::kFormat : ErrorCode::kInvalidArgument,
                "{}: the pattern description '{}' does not fit the images: {}", where, options.patterns.name,
                error.what());
  }
}

void check_sizes(const std::vector<Image16u>& stack, const std::vector<std::string>& paths, const std::string& first,
                 int width, int height) {
  for (std::size_t k = 0; k < stack.size(); ++k) {
    if (stack[k].width() != width || stack[k].height() != height) {
      throw_error(ErrorCode::kInvalidArgument, "{} is {}x{}, {} is {}x{}: images of mixed sizes", paths[k],
                  stack[k].width(), stack[k].height(), first, width, height);
    }
  }
}

// Reads and appends every stack (the first already read) to the recording.
void write_frames(const std::vector<std::vector<std::string>>& stacks, int depth,
                  std::vector<Image16u> first, CaptureImportSummary& summary, RecordingWriter& writer,
                  const ProgressCallback& progress) {
  for (std::size_t s = 0; s < stacks.size(); ++s) {
    std::vector<Image16u> stack;
    if (s == 0) {
      stack = std::move(first);
    } else {
      stack.resize(stacks[s].size());
      for (std::size_t k = 0; k < stacks[s].size(); ++k) {
        int d = 0;
        stack[k] = read_image(stacks[s][k], &d);
        if (d != depth) {
          throw_error(ErrorCode::kInvalidArgument, "{} is {}-bit, {} is {}-bit: images of mixed bit depths",
                      stacks[s][k], d, stacks[0][0], depth);
        }
      }
      check_sizes(stack, stacks[s], stacks[0][0], summary.width, summary.height);
    }
    FrameMetadata metadata;
    metadata.timestamp_ns = static_cast<std::int64_t>(s) * 1000000000;  // unknown: one a second
    metadata.note = "imported from " + fs::path(stacks[s][0]).parent_path().generic_string();
    if (depth == 8) {
      std::vector<Image8u> narrow(stack.size());
      for (std::size_t k = 0; k < stack.size(); ++k) {
        narrow[k].resize(stack[k].width(), stack[k].height());
        std::transform(stack[k].data(), stack[k].data() + stack[k].pixel_count(), narrow[k].data(),
                       [](std::uint16_t v) { return static_cast<std::uint8_t>(v); });
      }
      writer.append_frame(narrow, metadata);
    } else {
      writer.append_frame(stack, metadata);
    }
    summary.stacks.push_back(fs::path(stacks[s][0]).parent_path().generic_string());
    ++summary.frames;
    report_progress(progress, {"import", s + 1, stacks.size(), stacks[s][0]});
  }
}

}  // namespace

std::vector<std::vector<std::string>> find_capture_stacks(const CaptureImportOptions& options) {
  const fs::path root(options.images);
  std::error_code error;
  if (!fs::is_directory(root, error)) throw_error(ErrorCode::kNotFound, "{}: not a folder of images", options.images);
  std::vector<std::vector<std::string>> stacks;
  std::vector<std::string> names;
  if (options.name_pattern.empty()) {
    const std::vector<fs::path> folders = entries(root, true);
    for (const fs::path& folder : folders) {
      std::vector<std::string> stack;
      for (const fs::path& file : entries(folder, false)) stack.push_back(file.string());
      if (stack.empty()) continue;  // not a stack (notes, a calibration folder)
      stacks.push_back(stack);
      names.push_back(folder.filename().string());
    }
    if (stacks.empty()) {
      std::vector<std::string> stack;
      for (const fs::path& file : entries(root, false)) stack.push_back(file.string());
      if (!stack.empty()) {
        stacks.push_back(stack);
        names.push_back(".");
      }
    }
  } else {
    check_name_pattern(options.name_pattern);
    std::vector<std::string> files;
    collect(root, root, &files);
    std::map<long long, std::map<long long, std::string>> by_frame;
    for (const std::string& file : files) {
      long long frame = 0, image = 0;
      if (!match_name(options.name_pattern, 0, file, 0, &frame, &image)) continue;
      auto [it, inserted] = by_frame[frame].emplace(image, (root / file).string());
      if (!inserted) {
        throw_error(ErrorCode::kInvalidArgument, "{}: {} and {} are both image {} of frame {}", options.images,
                    it->second, file, image, frame);
      }
    }
    for (const auto& [frame, images] : by_frame) {
      std::vector<std::string> stack;
      for (const auto& entry : images) stack.push_back(entry.second);
      stacks.push_back(stack);
      names.push_back(fmt::format("frame {}", frame));
    }
  }
  if (stacks.empty()) {
    throw_error(ErrorCode::kNotFound, "{}: no PNG, BMP or TIFF images{}", options.images,
                options.name_pattern.empty() ? "" : " named like '" + options.name_pattern + "'");
  }
  for (std::size_t i = 0; i < stacks.size(); ++i) {
    if (stacks[i].size() != options.patterns.size()) {
      throw_error(ErrorCode::kInvalidArgument,
                  "{}: stack {} ({}) holds {} images, the pattern description '{}' has {} patterns", options.images,
                  i, names[i], stacks[i].size(), options.patterns.name, options.patterns.size());
    }
  }
  return stacks;
}

CaptureImportSummary import_capture(const CaptureImportOptions& options, const ProgressCallback& progress) {
  validate_pattern_set(options.patterns);
  (void)make_decode_layout(options.patterns);  // a set the decoder cannot use fails here, not later
  if (options.bit_depth != 0 && (options.bit_depth < 9 || options.bit_depth > 16)) {
    throw_error(ErrorCode::kInvalidArgument, "bit depth {} of 16-bit images: 9..16 (or 0: 16)", options.bit_depth);
  }
  std::vector<std::vector<std::string>> stacks = find_capture_stacks(options);
  CaptureImportSummary summary;
  // Sizes from each stack's first image, before anything is written. Tools that capture
  // through a projector often save the patterns themselves beside the captures (e.g.
  // procam-calibration's graycode_pattern/): a stack of the projector's size among stacks of
  // another size is that, and is left out (and reported), not an error.
  {
    std::vector<std::pair<int, int>> sizes;
    for (const std::vector<std::string>& stack : stacks) {
      int d = 0;
      const Image16u image = read_image(stack.front(), &d);
      sizes.emplace_back(image.width(), image.height());
    }
    const std::pair<int, int> projector(options.patterns.projector_width, options.patterns.projector_height);
    const bool others = std::any_of(sizes.begin(), sizes.end(), [&](const auto& size) { return size != projector; });
    std::vector<std::vector<std::string>> kept;
    std::vector<std::pair<int, int>> kept_sizes;
    for (std::size_t s = 0; s < stacks.size(); ++s) {
      if (others && sizes[s] == projector) {
        summary.skipped.push_back(fs::path(stacks[s].front()).parent_path().generic_string());
        continue;
      }
      kept.push_back(stacks[s]);
      kept_sizes.push_back(sizes[s]);
    }
    stacks = kept;
    for (std::size_t s = 1; s < stacks.size(); ++s) {
      if (kept_sizes[s] != kept_sizes[0]) {
        throw_error(ErrorCode::kInvalidArgument, "{} is {}x{}, {} is {}x{}: images of mixed sizes", stacks[s].front(),
                    kept_sizes[s].first, kept_sizes[s].second, stacks[0].front(), kept_sizes[0].first,
                    kept_sizes[0].second);
      }
    }
  }
  int depth = 0;
  std::vector<Image16u> first(stacks[0].size());
  for (std::size_t k = 0; k < stacks[0].size(); ++k) {
    int d = 0;
    first[k] = read_image(stacks[0][k], &d);
    if (k == 0) depth = d;
    if (d != depth) {
      throw_error(ErrorCode::kInvalidArgument, "{} is {}-bit, {} is {}-bit: images of mixed bit depths",
                  stacks[0][k], d, stacks[0][0], depth);
    }
  }
  summary.width = first[0].width();
  summary.height = first[0].height();
  summary.bit_depth = depth == 8 ? 8 : (options.bit_depth > 0 ? options.bit_depth : 16);
  summary.images_per_frame = static_cast<int>(options.patterns.size());

  CalibrationImportOptions calibration_options;
  calibration_options.camera_width = summary.width;
  calibration_options.camera_height = summary.height;
  calibration_options.projector_width = options.patterns.projector_width;
  calibration_options.projector_height = options.patterns.projector_height;
  calibration_options.unit_m = options.unit_m;
  const ImportedCalibration calibration = import_calibration(options.calibration, calibration_options);
  summary.calibration_layout = calibration.layout;
  const ScannerCalibration& c = calibration.calibration;
  if (c.camera.width != summary.width || c.camera.height != summary.height) {
    throw_error(ErrorCode::kInvalidArgument, "{}: a calibration of a {}x{} camera for {}x{} images",
                options.calibration, c.camera.width, c.camera.height, summary.width, summary.height);
  }

  RecordingInfo info;
  info.device = {"import://" + fs::absolute(options.images).lexically_normal().generic_string(), "imported capture",
                 ""};
  info.camera = {summary.width, summary.height, summary.bit_depth};
  info.pattern_set_json = pattern_set_to_json(options.patterns);
  info.images_per_frame = summary.images_per_frame;
  RecordingWriterOptions writer_options;
  writer_options.sync = false;  // the sources stay: an interrupted import is simply run again
  check_sizes(first, stacks[0], stacks[0][0], summary.width, summary.height);
  if (options.check) {
    summary.checked_fraction = check_description(options, c, first, summary.bit_depth, stacks[0][0]);
  }
  std::error_code listing;
  const bool existed = fs::exists(options.out, listing);
  RecordingWriter writer = RecordingWriter::create(options.out, info, c, writer_options);
  try {
    write_frames(stacks, depth, std::move(first), summary, writer, progress);
  } catch (...) {
    // A half import is no recording of the capture: the folder it made goes (the sources stay).
    std::error_code ignored;
    if (!existed) {
      fs::remove_all(options.out, ignored);
    } else {
      for (const fs::directory_entry& entry : fs::directory_iterator(options.out, ignored)) {
        fs::remove_all(entry.path(), ignored);
      }
    }
    throw;
  }
  writer.close();
  return summary;
}

}  // namespace sls::calib
