#include "sdk/decode/pattern_families.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>

#include <fmt/format.h>

#include <nlohmann/json.hpp>

#include "sdk/core/error.h"
#include "sdk/decode/decode_shared.h"
#include "sdk/decode/decoder.h"

namespace sls {
namespace {

using Json = nlohmann::ordered_json;

constexpr int kMaxSide = 1 << 16;

[[noreturn]] void bad(const std::string& what) {
  throw Error(ErrorCode::kInvalidArgument, what);
}

[[noreturn]] void bad_format(const std::string& what) {
  throw Error(ErrorCode::kFormat, "pattern description: " + what);
}

void check_projector(const char* family, int width, int height, bool columns, bool rows) {
  if (width <= 0 || height <= 0 || width > kMaxSide || height > kMaxSide) {
    bad(fmt::format("{} pattern set: projector size {}x{} is unusable", family, width, height));
  }
  if (!columns && !rows) bad(fmt::format("{} pattern set: neither columns nor rows are encoded", family));
}

PatternDesc reference(PatternKind kind, int width) {
  PatternDesc d;
  d.kind = kind;
  d.extent = width;
  return d;
}

std::string period_text(double period) {
  return period == std::floor(period) ? fmt::format("{}", static_cast<long long>(period)) : fmt::format("{:.3f}", period);
}

}  // namespace

PatternSet make_gray_code_pattern_set(const GrayCodeOptions& o) {
  check_projector("Gray-code", o.projector_width, o.projector_height, o.columns, o.rows);
  if (!o.inverse && o.references == ReferencePlacement::kNone) {
    bad("Gray-code pattern set: without inverse patterns it needs white and black to threshold against");
  }
  PatternSet set;
  set.kind = PatternSetKind::kGrayCode;
  set.projector_width = o.projector_width;
  set.projector_height = o.projector_height;
  if (o.references == ReferencePlacement::kFirst) {
    set.patterns.push_back(reference(PatternKind::kWhite, o.projector_width));
    set.patterns.push_back(reference(PatternKind::kBlack, o.projector_width));
  }
  for (const PatternAxis axis : {PatternAxis::kColumns, PatternAxis::kRows}) {
    if (!(axis == PatternAxis::kColumns ? o.columns : o.rows)) continue;
    const int extent = axis == PatternAxis::kColumns ? o.projector_width : o.projector_height;
    for (int bit = gray_code_bits(extent) - 1; bit >= 0; --bit) {
      PatternDesc d;
      d.kind = PatternKind::kGrayCode;
      d.axis = axis;
      d.extent = extent;
      d.bit = bit;
      set.patterns.push_back(d);
      if (o.inverse) {
        d.inverted = true;
        set.patterns.push_back(d);
      }
    }
  }
  if (o.references == ReferencePlacement::kLast) {
    set.patterns.push_back(reference(PatternKind::kWhite, o.projector_width));
    set.patterns.push_back(reference(PatternKind::kBlack, o.projector_width));
  }
  set.name = !o.name.empty() ? o.name
                             : fmt::format("gray_code_{}x{}{}{}", o.projector_width, o.projector_height,
                                           o.columns ? (o.rows ? "" : "_c") : "_r", o.inverse ? "" : "_noinv");
  validate_pattern_set(set);
  return set;
}

PatternSet make_phase_shift_pattern_set(const PhaseShiftOptions& o) {
  check_projector("phase-shift", o.projector_width, o.projector_height, o.columns, o.rows);
  if (o.steps < 3 || o.steps > kDecodeMaxPhaseSteps) {
    bad(fmt::format("phase-shift pattern set: {} steps (need 3..{})", o.steps, kDecodeMaxPhaseSteps));
  }
  std::vector<int> order = o.step_order;
  if (order.empty()) {
    for (int j = 0; j < o.steps; ++j) order.push_back(j);
  }
  std::vector<int> sorted = order;
  std::sort(sorted.begin(), sorted.end());
  for (int j = 0; j < o.steps; ++j) {
    if (sorted.size() != static_cast<std::size_t>(o.steps) || sorted[static_cast<std::size_t>(j)] != j) {
      bad(fmt::format("phase-shift pattern set: step_order must list each of the steps 0..{} once", o.steps - 1));
    }
  }
  if (!(o.gray_shift_px >= 0.0) || !std::isfinite(o.gray_shift_px)) {
    bad(fmt::format("phase-shift pattern set: gray_shift_px {} must be >= 0", o.gray_shift_px));
  }
  const bool heterodyne = o.unwrap == PhaseUnwrap::kHeterodyne;
  if (heterodyne && o.gray_shift_px != 0.0) {
    bad("phase-shift pattern set: gray_shift_px with heterodyne unwrapping, which projects no Gray code");
  }
  PatternSet set;
  set.kind = heterodyne ? PatternSetKind::kHeterodyne : PatternSetKind::kPhaseShift;
  set.projector_width = o.projector_width;
  set.projector_height = o.projector_height;
  set.gray_threshold = heterodyne ? GrayThresholdMode::kAuto : o.gray_threshold;
  if (o.references) {
    set.patterns.push_back(reference(PatternKind::kWhite, o.projector_width));
    set.patterns.push_back(reference(PatternKind::kBlack, o.projector_width));
  }
  std::string name = "phase_shift";
  for (const PatternAxis axis : {PatternAxis::kColumns, PatternAxis::kRows}) {
    if (!(axis == PatternAxis::kColumns ? o.columns : o.rows)) continue;
    const int extent = axis == PatternAxis::kColumns ? o.projector_width : o.projector_height;
    std::vector<double> periods =
        axis == PatternAxis::kRows && !o.row_periods_px.empty() ? o.row_periods_px : o.periods_px;
    if (periods.empty() || periods.size() > static_cast<std::size_t>(kDecodeMaxPhaseGroups)) {
      bad(fmt::format("phase-shift pattern set: {} periods (need 1..{})", periods.size(), kDecodeMaxPhaseGroups));
    }
    std::sort(periods.begin(), periods.end(), std::greater<>());
    for (std::size_t i = 0; i < periods.size(); ++i) {
      if (!(periods[i] >= 3.0 && periods[i] <= kMaxSide)) {
        bad(fmt::format("phase-shift pattern set: period {} px (need 3..{})", periods[i], kMaxSide));
      }
      if (i > 0 && periods[i] == periods[i - 1]) bad("phase-shift pattern set: a period is listed twice");
    }
    name += fmt::format("_{}{}", axis == PatternAxis::kColumns ? 'c' : 'r', o.steps);
    const double coarsest = periods.front();
    if (heterodyne) {
      if (periods.size() < 2) {
        bad(fmt::format("phase-shift pattern set: heterodyne unwrapping beats two or three periods, the {} have one",
                        axis == PatternAxis::kColumns ? "columns" : "rows"));
      }
      name += "h";
    } else if (o.unwrap != PhaseUnwrap::kNone) {
      PatternDesc d;
      d.kind = PatternKind::kGrayCode;
      d.axis = axis;
      d.extent = extent;
      d.gray_unit_px = o.unwrap == PhaseUnwrap::kGray ? coarsest : 0.5 * coarsest;
      d.gray_origin_px = -o.gray_shift_px;
      if (d.gray_unit_px == 1.0 && d.gray_origin_px == 0.0) d.gray_unit_px = 0.0;  // the pixel code
      for (int bit = gray_code_bits(d) - 1; bit >= 0; --bit) {
        d.bit = bit;
        d.inverted = false;
        set.patterns.push_back(d);
        if (o.gray_inverse) {
          d.inverted = true;
          set.patterns.push_back(d);
        }
      }
      name += o.unwrap == PhaseUnwrap::kGray ? "g" : "cg";
    } else if (coarsest < extent) {
      bad(fmt::format("phase-shift pattern set: unwrap \"none\" needs a period spanning the {} {} (the coarsest is "
                      "{} px)",
                      extent, axis == PatternAxis::kColumns ? "columns" : "rows", coarsest));
    }
    for (const double period : periods) {
      name += "p" + period_text(period);
      for (const int step : order) {
        PatternDesc d;
        d.kind = PatternKind::kPhaseShift;
        d.axis = axis;
        d.extent = extent;
        d.step = step;
        d.steps = o.steps;
        d.period_px = period;
        d.phase_reversed = o.reversed;
        d.phase_offset_rad = o.offset_rad;
        set.patterns.push_back(d);
      }
    }
  }
  set.name = o.name.empty() ? name : o.name;
  validate_pattern_set(set);
  if (heterodyne) (void)make_decode_layout(set);  // the beats must number each axis
  return set;
}

PatternSet make_micro_phase_pattern_set(const MicroPhaseOptions& o) {
  check_projector("micro phase-shifting", o.projector_width, o.projector_height, o.columns, o.rows);
  if (o.steps < 3 || o.steps > kDecodeMaxPhaseSteps) {
    bad(fmt::format("micro phase-shifting pattern set: {} steps (need 3..{})", o.steps, kDecodeMaxPhaseSteps));
  }
  PatternSet set;
  set.kind = PatternSetKind::kMicroPhase;
  set.projector_width = o.projector_width;
  set.projector_height = o.projector_height;
  if (o.references) {
    set.patterns.push_back(reference(PatternKind::kWhite, o.projector_width));
    set.patterns.push_back(reference(PatternKind::kBlack, o.projector_width));
  }
  std::string name = "micro_phase";
  for (const PatternAxis axis : {PatternAxis::kColumns, PatternAxis::kRows}) {
    if (!(axis == PatternAxis::kColumns ? o.columns : o.rows)) continue;
    const int extent = axis == PatternAxis::kColumns ? o.projector_width : o.projector_height;
    const std::vector<double>& periods =
        axis == PatternAxis::kRows && !o.row_periods_px.empty() ? o.row_periods_px : o.periods_px;
    if (periods.size() < 2 || periods.size() > static_cast<std::size_t>(kDecodeMaxMicroSingles) + 1) {
      bad(fmt::format("micro phase-shifting pattern set: {} periods (need 2..{})", periods.size(),
                      kDecodeMaxMicroSingles + 1));
    }
    for (std::size_t i = 0; i < periods.size(); ++i) {
      if (!(periods[i] >= 3.0 && periods[i] <= kMaxSide)) {
        bad(fmt::format("micro phase-shifting pattern set: period {} px (need 3..{})", periods[i], kMaxSide));
      }
      if (std::count(periods.begin(), periods.end(), periods[i]) > 1) {
        bad(fmt::format("micro phase-shifting pattern set: period {} px is listed twice", periods[i]));
      }
    }
    name += fmt::format("_{}{}p{}f{}", axis == PatternAxis::kColumns ? 'c' : 'r', o.steps, period_text(periods[0]),
                        periods.size());
    // The first period's N steps, then one image (step 0) of each other period.
    for (std::size_t i = 0; i < periods.size(); ++i) {
      for (int step = 0; step < (i == 0 ? o.steps : 1); ++step) {
        PatternDesc d;
        d.kind = PatternKind::kPhaseShift;
        d.axis = axis;
        d.extent = extent;
        d.step = step;
        d.steps = o.steps;
        d.period_px = periods[i];
        d.phase_reversed = o.reversed;
        d.phase_offset_rad = o.offset_rad;
        set.patterns.push_back(d);
      }
    }
  }
  set.name = o.name.empty() ? name : o.name;
  validate_pattern_set(set);
  (void)make_decode_layout(set);  // the single images must tell the periods apart
  return set;
}

// --- Description files ---------------------------------------------------------------------

namespace {

class Reader {
 public:
  explicit Reader(const Json& root) : root_(root) {}

  bool has(const char* key) {
    used_.insert(key);
    return root_.contains(key);
  }
  const Json& at(const char* key) {
    used_.insert(key);
    auto it = root_.find(key);
    if (it == root_.end()) bad_format(fmt::format("missing \"{}\"", key));
    return *it;
  }
  int integer(const char* key, int fallback) {
    if (!has(key)) return fallback;
    const Json& v = at(key);
    if (!v.is_number_integer() || v.get<std::int64_t>() < -kMaxSide || v.get<std::int64_t>() > kMaxSide) {
      bad_format(fmt::format("\"{}\" is not an integer in range", key));
    }
    return v.get<int>();
  }
  double number(const char* key, double fallback) {
    if (!has(key)) return fallback;
    const Json& v = at(key);
    if (!v.is_number() || !std::isfinite(v.get<double>())) bad_format(fmt::format("\"{}\" is not a number", key));
    return v.get<double>();
  }
  bool boolean(const char* key, bool fallback) {
    if (!has(key)) return fallback;
    const Json& v = at(key);
    if (!v.is_boolean()) bad_format(fmt::format("\"{}\" is not a boolean", key));
    return v.get<bool>();
  }
  std::string text(const char* key, const std::string& fallback, std::initializer_list<const char*> allowed) {
    if (!has(key)) return fallback;
    const Json& v = at(key);
    std::string names;
    for (const char* a : allowed) {
      if (v.is_string() && v.get<std::string>() == a) return a;
      names += std::string(names.empty() ? "" : ", ") + a;
    }
    bad_format(fmt::format("\"{}\" must be one of {}", key, names));
  }
  std::vector<double> numbers(const char* key) {
    std::vector<double> out;
    if (!has(key)) return out;
    const Json& given = at(key);
    const Json v = given.is_number() ? Json::array({given}) : given;
    if (!v.is_array()) bad_format(fmt::format("\"{}\" is not a number or a list of numbers", key));
    for (const Json& e : v) {
      if (!e.is_number() || !std::isfinite(e.get<double>())) bad_format(fmt::format("\"{}\" holds a non-number", key));
      out.push_back(e.get<double>());
    }
    return out;
  }
  // Keys this family does not know are typos, not silently defaults.
  void reject_unknown(const char* family) const {
    for (auto it = root_.begin(); it != root_.end(); ++it) {
      if (used_.count(it.key()) == 0 && it.key() != "comment") {
        bad_format(fmt::format("family \"{}\" has no parameter \"{}\"", family, it.key()));
      }
    }
  }

 private:
  const Json& root_;
  std::set<std::string> used_;
};

void read_direction(Reader& r, bool* columns, bool* rows, const char* fallback) {
  const std::string direction = r.text("direction", fallback, {"columns", "rows", "both"});
  *columns = direction != "rows";
  *rows = direction != "columns";
}

// "phase_sign": 1 or -1 (PatternDesc::phase_reversed).
bool read_sign(Reader& r) {
  const int sign = r.integer("phase_sign", 1);
  if (sign != 1 && sign != -1) bad_format("\"phase_sign\" must be 1 or -1");
  return sign < 0;
}

GrayThresholdMode read_threshold(Reader& r) {
  const std::string t = r.text("gray_threshold", "auto", {"auto", "white_black", "phase_mean"});
  return t == "white_black" ? GrayThresholdMode::kWhiteBlack
         : t == "phase_mean" ? GrayThresholdMode::kPhaseMean
                             : GrayThresholdMode::kAuto;
}

}  // namespace

PatternSet pattern_set_from_description(const std::string& text) {
  Json root;
  try {
    root = Json::parse(text);
  } catch (const Json::exception& error) {
    bad_format(std::string("not valid JSON: ") + error.what());
  }
  if (!root.is_object()) bad_format("the top level is not an object");
  if (root.contains("patterns")) return pattern_set_from_json(text);  // the explicit list
  Reader r(root);
  const std::string format = r.text("format", "slscan-pattern-set", {"slscan-pattern-set"});
  const int version = r.integer("format_version", 2);
  if (version > 2) {
    throw_error(ErrorCode::kVersionMismatch, "pattern description: format_version {} is newer than this SDK's 2",
                version);
  }
  // No family: slscan's own (what recordings made before descriptions existed use).
  const std::string family =
      r.text("family", "gray_phase", {"gray_phase", "gray_code", "phase_shift", "micro_phase"});
  const std::string name = r.has("name") && r.at("name").is_string() ? r.at("name").get<std::string>() : "";
  int width = 0, height = 0;
  if (r.has("projector")) {
    const Json& p = r.at("projector");
    if (!p.is_object()) bad_format("\"projector\" is not an object");
    Reader pr(p);
    width = pr.integer("width", 0);
    height = pr.integer("height", 0);
    pr.boolean("diamond", false);  // informational (docs: the DLP4500's diamond pixels)
    pr.reject_unknown("projector");
  }
  PatternSet set;
  if (family == "gray_phase") {
    GrayPhaseOptions o;
    if (width > 0) o.projector_width = width;
    if (height > 0) o.projector_height = height;
    read_direction(r, &o.columns, &o.rows, "columns");
    o.phase_steps = r.integer("steps", o.phase_steps);
    o.phase_period_px = r.integer("period_px", o.phase_period_px);
    o.row_phase_period_px = r.integer("row_period_px", o.row_phase_period_px);
    o.gray_lowest_bit = r.integer("gray_lowest_bit", o.gray_lowest_bit);
    o.inverse_gray = r.boolean("inverse", o.inverse_gray);
    o.references = r.text("references", "first", {"first", "none"}) == "first";
    o.name = name;
    r.reject_unknown("gray_phase");
    set = make_gray_phase_pattern_set(o);
  } else if (family == "gray_code") {
    GrayCodeOptions o;
    if (width > 0) o.projector_width = width;
    if (height > 0) o.projector_height = height;
    read_direction(r, &o.columns, &o.rows, "both");
    const std::string order = r.text("order", "opencv", {"opencv", "slscan"});
    const std::string refs = r.text("references", order == "opencv" ? "last" : "first", {"first", "last", "none"});
    o.references = refs == "first" ? ReferencePlacement::kFirst
                   : refs == "last" ? ReferencePlacement::kLast
                                    : ReferencePlacement::kNone;
    o.inverse = r.boolean("inverse", true);
    o.name = name;
    r.reject_unknown("gray_code");
    set = make_gray_code_pattern_set(o);
  } else if (family == "micro_phase") {
    MicroPhaseOptions o;
    if (width > 0) o.projector_width = width;
    if (height > 0) o.projector_height = height;
    read_direction(r, &o.columns, &o.rows, "columns");
    o.steps = r.integer("steps", o.steps);
    const std::vector<double> periods = r.numbers("periods_px");
    if (!periods.empty()) o.periods_px = periods;
    o.row_periods_px = r.numbers("row_periods_px");
    o.reversed = read_sign(r);
    o.offset_rad = r.number("phase_offset_rad", 0.0);
    o.references = r.text("references", "first", {"first", "none"}) == "first";
    o.name = name;
    r.reject_unknown("micro_phase");
    set = make_micro_phase_pattern_set(o);
  } else {
    PhaseShiftOptions o;
    if (width > 0) o.projector_width = width;
    if (height > 0) o.projector_height = height;
    read_direction(r, &o.columns, &o.rows, "columns");
    o.steps = r.integer("steps", o.steps);
    if (r.has("step_order")) {
      const Json& order = r.at("step_order");
      if (!order.is_array()) bad_format("\"step_order\" is not a list");
      for (const Json& e : order) {
        if (!e.is_number_integer()) bad_format("\"step_order\" holds a non-integer");
        o.step_order.push_back(e.get<int>());
      }
    }
    const std::vector<double> periods = r.numbers("periods_px");
    if (!periods.empty()) o.periods_px = periods;
    o.row_periods_px = r.numbers("row_periods_px");
    o.reversed = read_sign(r);
    o.offset_rad = r.number("phase_offset_rad", 0.0);
    const std::string unwrap =
        r.text("unwrap", "complementary_gray", {"gray", "complementary_gray", "none", "heterodyne"});
    o.unwrap = unwrap == "gray"         ? PhaseUnwrap::kGray
               : unwrap == "none"       ? PhaseUnwrap::kNone
               : unwrap == "heterodyne" ? PhaseUnwrap::kHeterodyne
                                        : PhaseUnwrap::kComplementaryGray;
    if (o.unwrap == PhaseUnwrap::kHeterodyne) {
      for (const char* key : {"gray_inverse", "gray_shift_px", "gray_threshold"}) {
        if (r.has(key)) {
          bad_format(fmt::format("\"{}\" has no meaning with \"unwrap\": \"heterodyne\" (no Gray code)", key));
        }
      }
    }
    o.gray_inverse = r.boolean("gray_inverse", true);
    o.gray_shift_px = r.number("gray_shift_px", 0.0);
    o.references = r.text("references", "first", {"first", "none"}) == "first";
    o.gray_threshold = read_threshold(r);
    o.name = name;
    r.reject_unknown("phase_shift");
    set = make_phase_shift_pattern_set(o);
  }
  (void)format;
  return set;
}

PatternSet load_pattern_description(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw_error(ErrorCode::kNotFound, "pattern description {}: cannot open it", path);
  std::ostringstream text;
  text << in.rdbuf();
  try {
    return pattern_set_from_description(text.str());
  } catch (const Error& error) {
    throw Error(error.code(), path + ": " + error.what());
  }
}

}  // namespace sls
