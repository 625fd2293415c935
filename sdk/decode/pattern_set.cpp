#include "sdk/decode/pattern_set.h"

#include <cmath>
#include <cstdio>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "sdk/core/error.h"

namespace sls {
namespace {

using Json = nlohmann::ordered_json;

constexpr const char* kFormatName = "slscan-pattern-set";
constexpr int kFormatVersion = 2;  // 1: slscan's own fields only (still written when enough)
// Far above any DMD (the largest are 4K); keeps extent * steps products and images sane.
constexpr int kMaxProjectorSide = 1 << 16;
constexpr int kMaxPhaseSteps = 1024;
constexpr int kMaxPeriod = 1 << 16;

const char* axis_name(PatternAxis axis) { return axis == PatternAxis::kRows ? "rows" : "columns"; }

const char* kind_name(PatternKind kind) {
  switch (kind) {
    case PatternKind::kWhite:
      return "white";
    case PatternKind::kBlack:
      return "black";
    case PatternKind::kGrayCode:
      return "gray_code";
    case PatternKind::kPhaseShift:
      return "phase_shift";
  }
  return "unknown";
}


int extent_for(PatternAxis axis, int width, int height) { return axis == PatternAxis::kRows ? height : width; }

PatternDesc make_reference(PatternKind kind, int width) {
  PatternDesc d;
  d.kind = kind;
  d.axis = PatternAxis::kColumns;
  d.extent = width;
  return d;
}

void add_axis(PatternSet& set, PatternAxis axis, const GrayPhaseOptions& options, int period) {
  const int extent = extent_for(axis, set.projector_width, set.projector_height);
  const int bits = gray_code_bits(extent);
  const int lowest = options.gray_lowest_bit < 0 ? automatic_gray_lowest_bit(period) : options.gray_lowest_bit;
  for (int bit = bits - 1; bit >= lowest && bit >= 0; --bit) {
    PatternDesc d;
    d.kind = PatternKind::kGrayCode;
    d.axis = axis;
    d.extent = extent;
    d.bit = bit;
    set.patterns.push_back(d);
    if (options.inverse_gray) {
      d.inverted = true;
      set.patterns.push_back(d);
    }
  }
  for (int step = 0; step < options.phase_steps; ++step) {
    PatternDesc d;
    d.kind = PatternKind::kPhaseShift;
    d.axis = axis;
    d.extent = extent;
    d.step = step;
    d.steps = options.phase_steps;
    d.period_px = period;
    set.patterns.push_back(d);
  }
}

[[noreturn]] void throw_format(const std::string& what) {
  throw Error(ErrorCode::kFormat, "pattern set JSON: " + what);
}

// Returns a pointer, not a reference: GCC 13's -Wdangling-reference would take a reference
// returned next to the temporary `where` string for one into it.
const Json* member(const Json& object, const char* key, const std::string& where) {
  auto it = object.find(key);
  if (it == object.end()) throw_format(fmt::format("{}: missing \"{}\"", where, key));
  return &*it;
}

int int_member(const Json& object, const char* key, const std::string& where) {
  const Json& value = *member(object, key, where);
  if (!value.is_number_integer()) throw_format(fmt::format("{}: \"{}\" is not an integer", where, key));
  const auto number = value.get<std::int64_t>();
  if (number < -(std::int64_t{1} << 31) || number >= (std::int64_t{1} << 31)) {
    throw_format(fmt::format("{}: \"{}\" = {} is out of range", where, key, number));
  }
  return static_cast<int>(number);
}

std::string string_member(const Json& object, const char* key, const std::string& where) {
  const Json& value = *member(object, key, where);
  if (!value.is_string()) throw_format(fmt::format("{}: \"{}\" is not a string", where, key));
  return value.get<std::string>();
}

bool bool_member(const Json& object, const char* key, const std::string& where) {
  const Json& value = *member(object, key, where);
  if (!value.is_boolean()) throw_format(fmt::format("{}: \"{}\" is not a boolean", where, key));
  return value.get<bool>();
}

double number_member(const Json& object, const char* key, const std::string& where) {
  const Json& value = *member(object, key, where);
  if (!value.is_number() || !std::isfinite(value.get<double>())) {
    throw_format(fmt::format("{}: \"{}\" is not a finite number", where, key));
  }
  return value.get<double>();
}

double optional_number(const Json& object, const char* key, const std::string& where, double fallback) {
  return object.contains(key) ? number_member(object, key, where) : fallback;
}

// A number as JSON: integers stay integers (version-1 readers and the tests read them so).
Json number_json(double value) {
  if (value == std::floor(value) && std::fabs(value) < 2147483647.0) return static_cast<std::int64_t>(value);
  return value;
}

bool uses_version_2(const PatternSet& set) {
  if (set.kind != PatternSetKind::kGrayPhase && set.kind != PatternSetKind::kHeterodyne) return true;
  if (set.gray_threshold != GrayThresholdMode::kAuto) return true;
  for (const PatternDesc& d : set.patterns) {
    if (d.period_px != std::floor(d.period_px) || d.phase_reversed || d.phase_offset_rad != 0.0 ||
        d.gray_unit_px != 0.0 || d.gray_origin_px != 0.0) {
      return true;
    }
  }
  return false;
}

PatternAxis parse_axis(const Json& object, const std::string& where) {
  const std::string axis = string_member(object, "axis", where);
  if (axis == "columns") return PatternAxis::kColumns;
  if (axis == "rows") return PatternAxis::kRows;
  throw_format(fmt::format("{}: unknown axis \"{}\" (expected \"columns\" or \"rows\")", where, axis));
}

PatternDesc parse_pattern(const Json& object, int width, int height, const std::string& where) {
  if (!object.is_object()) throw_format(where + ": is not an object");
  const std::string kind = string_member(object, "kind", where);
  PatternDesc d;
  if (kind == "white" || kind == "black") {
    d = make_reference(kind == "white" ? PatternKind::kWhite : PatternKind::kBlack, width);
  } else if (kind == "gray_code") {
    d.kind = PatternKind::kGrayCode;
    d.axis = parse_axis(object, where);
    d.bit = int_member(object, "bit", where);
    d.inverted = bool_member(object, "inverted", where);
    d.gray_unit_px = optional_number(object, "unit_px", where, 0.0);
    d.gray_origin_px = optional_number(object, "origin_px", where, 0.0);
  } else if (kind == "phase_shift") {
    d.kind = PatternKind::kPhaseShift;
    d.axis = parse_axis(object, where);
    d.step = int_member(object, "step", where);
    d.steps = int_member(object, "steps", where);
    d.period_px = number_member(object, "period_px", where);
    d.phase_reversed = object.contains("reversed") && bool_member(object, "reversed", where);
    d.phase_offset_rad = optional_number(object, "offset_rad", where, 0.0);
  } else {
    throw_format(fmt::format("{}: unknown pattern kind \"{}\"", where, kind));
  }
  d.extent = extent_for(d.axis, width, height);
  return d;
}

}  // namespace

int gray_code_bits(int extent) {
  int bits = 0;
  while (bits < 31 && (std::int64_t{1} << bits) < extent) ++bits;
  return bits;
}

int gray_code_bits(const PatternDesc& d) {
  if (d.extent <= 0) return 0;
  const std::int64_t last = gray_stripe_of(d, d.extent - 1);
  if (last < 0 || last >= (std::int64_t{1} << 31)) return 31;
  return gray_code_bits(static_cast<int>(last + 1));
}

const char* pattern_set_kind_name(PatternSetKind kind) {
  switch (kind) {
    case PatternSetKind::kGrayPhase:
      return "gray_phase";
    case PatternSetKind::kHeterodyne:
      return "heterodyne";
    case PatternSetKind::kGrayCode:
      return "gray_code";
    case PatternSetKind::kPhaseShift:
      return "phase_shift";
    case PatternSetKind::kMicroPhase:
      return "micro_phase";
  }
  return "unknown";
}

int automatic_gray_lowest_bit(int phase_period_px) {
  int log2_period = 0;
  while (log2_period < 30 && (std::int64_t{2} << log2_period) <= phase_period_px) ++log2_period;
  return log2_period > 0 ? log2_period - 1 : 0;
}

PatternSet make_gray_phase_pattern_set(const GrayPhaseOptions& options) {
  if (options.projector_width <= 0 || options.projector_height <= 0 || options.projector_width > kMaxProjectorSide ||
      options.projector_height > kMaxProjectorSide) {
    throw_error(ErrorCode::kInvalidArgument, "gray/phase pattern set: projector size {}x{} is unusable",
                options.projector_width, options.projector_height);
  }
  if (!options.columns && !options.rows) {
    throw_error(ErrorCode::kInvalidArgument, "gray/phase pattern set: neither columns nor rows are encoded");
  }
  if (options.phase_steps < 3 || options.phase_steps > kMaxPhaseSteps) {
    throw_error(ErrorCode::kInvalidArgument, "gray/phase pattern set: {} phase steps (need 3..{})",
                options.phase_steps, kMaxPhaseSteps);
  }
  const int row_period = options.row_phase_period_px > 0 ? options.row_phase_period_px : options.phase_period_px;
  for (int period : {options.phase_period_px, row_period}) {
    if (period < 3 || period > kMaxPeriod) {
      throw_error(ErrorCode::kInvalidArgument, "gray/phase pattern set: phase period {} px (need 3..{})", period,
                  kMaxPeriod);
    }
  }
  if (options.gray_lowest_bit > 30) {
    throw_error(ErrorCode::kInvalidArgument, "gray/phase pattern set: gray_lowest_bit {} is out of range",
                options.gray_lowest_bit);
  }

  PatternSet set;
  set.kind = PatternSetKind::kGrayPhase;
  set.projector_width = options.projector_width;
  set.projector_height = options.projector_height;
  if (options.references) {
    set.patterns.push_back(make_reference(PatternKind::kWhite, options.projector_width));
    set.patterns.push_back(make_reference(PatternKind::kBlack, options.projector_width));
  }
  std::string name = "gray_phase";
  if (options.columns) {
    add_axis(set, PatternAxis::kColumns, options, options.phase_period_px);
    const int lowest = options.gray_lowest_bit < 0 ? automatic_gray_lowest_bit(options.phase_period_px)
                                                   : options.gray_lowest_bit;
    name += fmt::format("_c{}-{}p{}n{}", gray_code_bits(options.projector_width) - 1, lowest,
                        options.phase_period_px, options.phase_steps);
  }
  if (options.rows) {
    add_axis(set, PatternAxis::kRows, options, row_period);
    const int lowest = options.gray_lowest_bit < 0 ? automatic_gray_lowest_bit(row_period) : options.gray_lowest_bit;
    name += fmt::format("_r{}-{}p{}n{}", gray_code_bits(options.projector_height) - 1, lowest, row_period,
                        options.phase_steps);
  }
  set.name = options.name.empty() ? name : options.name;
  validate_pattern_set(set);
  return set;
}

PatternSet make_opencv_graycode_pattern_set(int width, int height, bool references) {
  if (width <= 0 || height <= 0 || width > kMaxProjectorSide || height > kMaxProjectorSide) {
    throw_error(ErrorCode::kInvalidArgument, "OpenCV Gray-code pattern set: projector size {}x{} is unusable", width,
                height);
  }
  PatternSet set;
  set.name = fmt::format("opencv_graycode_{}x{}", width, height);
  set.kind = PatternSetKind::kGrayCode;
  set.projector_width = width;
  set.projector_height = height;
  for (const PatternAxis axis : {PatternAxis::kColumns, PatternAxis::kRows}) {
    const int extent = extent_for(axis, width, height);
    for (int bit = gray_code_bits(extent) - 1; bit >= 0; --bit) {
      for (const bool inverted : {false, true}) {
        PatternDesc d;
        d.kind = PatternKind::kGrayCode;
        d.axis = axis;
        d.extent = extent;
        d.bit = bit;
        d.inverted = inverted;
        set.patterns.push_back(d);
      }
    }
  }
  if (references) {
    set.patterns.push_back(make_reference(PatternKind::kWhite, width));
    set.patterns.push_back(make_reference(PatternKind::kBlack, width));
  }
  validate_pattern_set(set);
  return set;
}

PatternSet pattern_set_from_name(const std::string& name) {
  const std::size_t colon = name.find(':');
  const std::string family = name.substr(0, colon);
  int width = 0, height = 0;
  char trailing = 0;
  const bool sized = colon != std::string::npos &&
                     std::sscanf(name.c_str() + colon + 1, "%dx%d%c", &width, &height, &trailing) == 2;
  if (family == "opencv-graycode" || family == "gray-phase") {
    if (!sized) {
      throw_error(ErrorCode::kInvalidArgument, "pattern set name '{}': expected {}:WIDTHxHEIGHT (the projector's size)",
                  name, family);
    }
    if (family == "opencv-graycode") return make_opencv_graycode_pattern_set(width, height);
    GrayPhaseOptions options;
    options.projector_width = width;
    options.projector_height = height;
    options.rows = true;
    return make_gray_phase_pattern_set(options);
  }
  throw_error(ErrorCode::kInvalidArgument,
              "unknown pattern set name '{}' (known: opencv-graycode:WxH, gray-phase:WxH)", name);
}

void validate_pattern_set(const PatternSet& set) {
  if (set.projector_width <= 0 || set.projector_height <= 0 || set.projector_width > kMaxProjectorSide ||
      set.projector_height > kMaxProjectorSide) {
    throw_error(ErrorCode::kInvalidArgument, "pattern set \"{}\": projector size {}x{} is unusable", set.name,
                set.projector_width, set.projector_height);
  }
  if (static_cast<int>(set.kind) < 0 || static_cast<int>(set.kind) > static_cast<int>(PatternSetKind::kMicroPhase)) {
    throw_error(ErrorCode::kInvalidArgument, "pattern set \"{}\": unknown kind {}", set.name,
                static_cast<int>(set.kind));
  }
  if (set.patterns.empty()) throw_error(ErrorCode::kInvalidArgument, "pattern set \"{}\" is empty", set.name);
  for (std::size_t i = 0; i < set.patterns.size(); ++i) {
    const PatternDesc& d = set.patterns[i];
    if (d.axis != PatternAxis::kColumns && d.axis != PatternAxis::kRows) {
      throw_error(ErrorCode::kInvalidArgument, "pattern set \"{}\": pattern {} has an unknown axis", set.name, i);
    }
    const int extent = extent_for(d.axis, set.projector_width, set.projector_height);
    if (d.extent != extent) {
      throw_error(ErrorCode::kInvalidArgument, "pattern set \"{}\": pattern {} ({}) has extent {}, the {} are {}",
                  set.name, i, pattern_label(d), d.extent, axis_name(d.axis), extent);
    }
    switch (d.kind) {
      case PatternKind::kWhite:
      case PatternKind::kBlack:
        break;
      case PatternKind::kGrayCode:
        if (!std::isfinite(d.gray_unit_px) || !std::isfinite(d.gray_origin_px) ||
            (d.gray_unit_px != 0.0 && !(d.gray_unit_px >= 1.0 && d.gray_unit_px <= kMaxPeriod)) ||
            !(d.gray_origin_px <= 0.0 && d.gray_origin_px > -kMaxPeriod)) {
          throw_error(ErrorCode::kInvalidArgument,
                      "pattern set \"{}\": pattern {}: Gray stripe unit {} px (need 1..{}) or origin {} px (need "
                      "<= 0) is unusable",
                      set.name, i, d.gray_unit_px, kMaxPeriod, d.gray_origin_px);
        }
        if (d.bit < 0 || d.bit >= gray_code_bits(d)) {
          throw_error(ErrorCode::kInvalidArgument, "pattern set \"{}\": pattern {}: Gray bit {} outside 0..{} for {} {}",
                      set.name, i, d.bit, gray_code_bits(d) - 1, extent, axis_name(d.axis));
        }
        break;
      case PatternKind::kPhaseShift:
        if (d.steps < 3 || d.steps > kMaxPhaseSteps || d.step < 0 || d.step >= d.steps || !(d.period_px >= 3.0) ||
            !(d.period_px <= kMaxPeriod) || !std::isfinite(d.phase_offset_rad) ||
            !(std::fabs(d.phase_offset_rad) <= 1e3)) {
          throw_error(ErrorCode::kInvalidArgument,
                      "pattern set \"{}\": pattern {}: phase step {} of {}, period {} px is unusable", set.name, i,
                      d.step, d.steps, d.period_px);
        }
        break;
      default:
        throw_error(ErrorCode::kInvalidArgument, "pattern set \"{}\": pattern {} has unknown kind {}", set.name, i,
                    static_cast<int>(d.kind));
    }
  }
}

std::string pattern_label(const PatternDesc& d) {
  const char axis = d.axis == PatternAxis::kRows ? 'r' : 'c';
  switch (d.kind) {
    case PatternKind::kWhite:
      return "white";
    case PatternKind::kBlack:
      return "black";
    case PatternKind::kGrayCode:
      return fmt::format("gray_{}{}{}", axis, d.bit, d.inverted ? "_inv" : "");
    case PatternKind::kPhaseShift:
      return fmt::format("phase_{}_p{}_s{}of{}", axis, number_json(d.period_px).dump(), d.step, d.steps);
  }
  return "unknown";
}

std::string pattern_set_to_json(const PatternSet& set) {
  Json root = Json::object();
  root["format"] = kFormatName;
  root["format_version"] = uses_version_2(set) ? 2 : 1;
  root["name"] = set.name;
  root["kind"] = pattern_set_kind_name(set.kind);
  if (set.gray_threshold != GrayThresholdMode::kAuto) {
    root["gray_threshold"] = set.gray_threshold == GrayThresholdMode::kPhaseMean ? "phase_mean" : "white_black";
  }
  root["projector"] = {{"width", set.projector_width}, {"height", set.projector_height}};
  root["image_count"] = set.patterns.size();
  Json patterns = Json::array();
  for (const PatternDesc& d : set.patterns) {
    Json p = Json::object();
    p["kind"] = kind_name(d.kind);
    if (d.kind == PatternKind::kGrayCode) {
      p["axis"] = axis_name(d.axis);
      p["bit"] = d.bit;
      p["inverted"] = d.inverted;
      if (d.gray_unit_px != 0.0) p["unit_px"] = number_json(d.gray_unit_px);
      if (d.gray_origin_px != 0.0) p["origin_px"] = number_json(d.gray_origin_px);
    } else if (d.kind == PatternKind::kPhaseShift) {
      p["axis"] = axis_name(d.axis);
      p["step"] = d.step;
      p["steps"] = d.steps;
      p["period_px"] = number_json(d.period_px);
      if (d.phase_reversed) p["reversed"] = true;
      if (d.phase_offset_rad != 0.0) p["offset_rad"] = d.phase_offset_rad;
    }
    patterns.push_back(std::move(p));
  }
  root["patterns"] = std::move(patterns);
  return root.dump();
}

PatternSet pattern_set_from_json(const std::string& text) {
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::exception& error) {
    throw_format(std::string("not valid JSON: ") + error.what());
  }
  if (!root.is_object()) throw_format("the top level is not an object");
  const std::string format = string_member(root, "format", "top level");
  if (format != kFormatName) throw_format(fmt::format("format is \"{}\", expected \"{}\"", format, kFormatName));
  const int version = int_member(root, "format_version", "top level");
  if (version > kFormatVersion) {
    throw_error(ErrorCode::kVersionMismatch, "pattern set JSON: format_version {} is newer than this SDK's {}",
                version, kFormatVersion);
  }
  if (version < 1) throw_format(fmt::format("format_version {} is invalid", version));

  PatternSet set;
  set.name = string_member(root, "name", "top level");
  const std::string kind = string_member(root, "kind", "top level");
  bool known = false;
  for (int k = 0; k <= static_cast<int>(PatternSetKind::kMicroPhase); ++k) {
    if (kind == pattern_set_kind_name(static_cast<PatternSetKind>(k))) {
      set.kind = static_cast<PatternSetKind>(k);
      known = true;
    }
  }
  if (!known) throw_format(fmt::format("unknown set kind \"{}\"", kind));
  if (root.contains("gray_threshold")) {
    const std::string threshold = string_member(root, "gray_threshold", "top level");
    if (threshold == "white_black") {
      set.gray_threshold = GrayThresholdMode::kWhiteBlack;
    } else if (threshold == "phase_mean") {
      set.gray_threshold = GrayThresholdMode::kPhaseMean;
    } else if (threshold != "auto") {
      throw_format(fmt::format("unknown gray_threshold \"{}\" (white_black, phase_mean or auto)", threshold));
    }
  }
  const Json& projector = *member(root, "projector", "top level");
  if (!projector.is_object()) throw_format("\"projector\" is not an object");
  set.projector_width = int_member(projector, "width", "projector");
  set.projector_height = int_member(projector, "height", "projector");
  if (set.projector_width <= 0 || set.projector_height <= 0 || set.projector_width > kMaxProjectorSide ||
      set.projector_height > kMaxProjectorSide) {
    throw_format(fmt::format("projector size {}x{} is unusable", set.projector_width, set.projector_height));
  }
  const Json& patterns = *member(root, "patterns", "top level");
  if (!patterns.is_array()) throw_format("\"patterns\" is not an array");
  for (std::size_t i = 0; i < patterns.size(); ++i) {
    set.patterns.push_back(
        parse_pattern(patterns[i], set.projector_width, set.projector_height, fmt::format("patterns[{}]", i)));
  }
  if (root.contains("image_count")) {
    const int count = int_member(root, "image_count", "top level");
    if (count < 0 || static_cast<std::size_t>(count) != set.patterns.size()) {
      throw_format(fmt::format("image_count {} differs from the {} patterns listed", count, set.patterns.size()));
    }
  }
  validate_pattern_set(set);
  return set;
}

std::vector<std::uint8_t> pattern_levels(const PatternDesc& pattern) {
  if (pattern.extent < 0) {
    throw_error(ErrorCode::kInvalidArgument, "pattern_levels: extent {} is negative", pattern.extent);
  }
  std::vector<std::uint8_t> levels(static_cast<std::size_t>(pattern.extent));
  for (int k = 0; k < pattern.extent; ++k) {
    levels[static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(pattern_pixel_value(pattern, k));
  }
  return levels;
}

Image8u rasterize_pattern(const PatternDesc& pattern, int width, int height) {
  const int extent = extent_for(pattern.axis, width, height);
  if (width <= 0 || height <= 0 || pattern.extent != extent) {
    throw_error(ErrorCode::kInvalidArgument, "rasterize_pattern: {} of extent {} does not fit a {}x{} DMD",
                pattern_label(pattern), pattern.extent, width, height);
  }
  const std::vector<std::uint8_t> levels = pattern_levels(pattern);
  Image8u image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      image(x, y) = levels[static_cast<std::size_t>(pattern.axis == PatternAxis::kRows ? y : x)];
    }
  }
  return image;
}

Image8u rasterize_pattern(const PatternSet& set, std::size_t index) {
  if (index >= set.patterns.size()) {
    throw_error(ErrorCode::kInvalidArgument, "rasterize_pattern: index {} is outside the {} patterns of \"{}\"",
                index, set.patterns.size(), set.name);
  }
  return rasterize_pattern(set.patterns[index], set.projector_width, set.projector_height);
}

}  // namespace sls
