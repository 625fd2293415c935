// scene_from_json(): a scene description (Scene::to_json(), as a recording's
// groundtruth/scene.json holds it for `sls eval`) read key by key into make_*_scene()'s
// parameters.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "drivers/sim/scene.h"
#include "sdk/core/error.h"

namespace sls::sim {
namespace {

using Json = nlohmann::ordered_json;

// Reads the "parameters" object key by key; unknown keys are errors (typos would otherwise
// silently fall back to defaults).
class ParameterReader {
 public:
  ParameterReader(const std::string& scene, const Json& parameters) : scene_(scene), parameters_(parameters) {}

  template <typename F>
  void each(F&& handle) {
    for (auto it = parameters_.begin(); it != parameters_.end(); ++it) {
      if (!handle(it.key(), it.value())) {
        throw_error(ErrorCode::kInvalidArgument, "scene '{}' has no parameter '{}'", scene_, it.key());
      }
    }
  }
  double number(const std::string& key, const Json& v) const {
    if (!v.is_number()) throw_error(ErrorCode::kFormat, "scene parameter '{}' must be a number", key);
    return v.get<double>();
  }
  int integer(const std::string& key, const Json& v) const {
    if (!v.is_number_integer()) throw_error(ErrorCode::kFormat, "scene parameter '{}' must be an integer", key);
    return v.get<int>();
  }
  AlbedoT<double> albedo(const std::string& key, const Json& v, AlbedoT<double> a) const {
    if (v.is_number()) {
      a.base = v.get<double>();
      return a;
    }
    if (!v.is_object()) throw_error(ErrorCode::kFormat, "scene parameter '{}' must be a number or an object", key);
    for (auto it = v.begin(); it != v.end(); ++it) {
      if (it.key() == "base") {
        a.base = number("albedo.base", it.value());
      } else if (it.key() == "amplitude") {
        a.amplitude = number("albedo.amplitude", it.value());
      } else if (it.key() == "period_m") {
        a.period = number("albedo.period_m", it.value());
      } else {
        throw_error(ErrorCode::kInvalidArgument, "scene '{}' albedo has no parameter '{}'", scene_, it.key());
      }
    }
    return a;
  }

 private:
  std::string scene_;
  const Json& parameters_;
};

}  // namespace

Scene scene_from_json(const std::string& text) {
  Json j;
  try {
    j = Json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw_error(ErrorCode::kFormat, "scene description is not valid JSON: {}", e.what());
  }
  if (!j.is_object() || !j.contains("name") || !j["name"].is_string()) {
    throw_error(ErrorCode::kFormat, "scene description needs a string \"name\"");
  }
  const std::string name = j["name"].get<std::string>();
  const Json parameters = j.contains("parameters") ? j["parameters"] : Json::object();
  if (!parameters.is_object()) throw_error(ErrorCode::kFormat, "scene \"parameters\" must be an object");
  ParameterReader r(name, parameters);
  if (name == "knurled-screw") {
    KnurledScrewParameters p;
    r.each([&](const std::string& key, const Json& v) {
      if (key == "diameter_m") p.diameter = r.number(key, v);
      else if (key == "height_m") p.height = r.number(key, v);
      else if (key == "nominal_pitch_m") p.nominal_pitch = r.number(key, v);
      else if (key == "groove_angle_deg") p.groove_angle_deg = r.number(key, v);
      else if (key == "albedo") p.albedo = r.albedo(key, v, p.albedo);
      else return false;
      return true;
    });
    return make_knurled_screw_scene(p);
  }
  if (name == "knurled-knob") {
    KnurledKnobParameters p;
    r.each([&](const std::string& key, const Json& v) {
      if (key == "diameter_m") p.diameter = r.number(key, v);
      else if (key == "height_m") p.height = r.number(key, v);
      else if (key == "nominal_pitch_m") p.nominal_pitch = r.number(key, v);
      else if (key == "groove_angle_deg") p.groove_angle_deg = r.number(key, v);
      else if (key == "wave_amplitude_pitches") p.wave_amplitude_pitches = r.number(key, v);
      else if (key == "wave_length_m") p.wave_length = r.number(key, v);
      else if (key == "albedo") p.albedo = r.albedo(key, v, p.albedo);
      else return false;
      return true;
    });
    return make_knurled_knob_scene(p);
  }
  if (name == "plane") {
    PlaneParameters p;
    r.each([&](const std::string& key, const Json& v) {
      if (key == "half_extent_x_m") p.half_extent_x = r.number(key, v);
      else if (key == "half_extent_y_m") p.half_extent_y = r.number(key, v);
      else if (key == "albedo") p.albedo = r.number(key, v);
      else return false;
      return true;
    });
    return make_plane_scene(p);
  }
  if (name == "sphere") {
    SphereParameters p;
    r.each([&](const std::string& key, const Json& v) {
      if (key == "center_m") {
        if (!v.is_array() || v.size() != 3) throw_error(ErrorCode::kFormat, "scene parameter 'center_m' must be [x, y, z]");
        for (int i = 0; i < 3; ++i) p.center[i] = r.number(key, v[static_cast<std::size_t>(i)]);
      } else if (key == "radius_m") {
        p.radius = r.number(key, v);
      } else if (key == "albedo") {
        p.albedo = r.number(key, v);
      } else {
        return false;
      }
      return true;
    });
    return make_sphere_scene(p);
  }
  if (name == "chessboard" || name == "charuco") {
    ChessboardParameters p;
    r.each([&](const std::string& key, const Json& v) {
      if (key == "charuco" && name == "charuco") {  // the table as written (make_chessboard_scene)
        try {
          p.charuco.marker = v.at("marker_m").get<double>();
          p.charuco.cells = v.at("marker_cells").get<int>();
          p.charuco.dictionary = v.at("dictionary").get<std::string>();
          p.charuco.dark_square = v.at("dark_square").get<std::vector<std::uint8_t>>();
          p.charuco.dark_cells = v.at("dark_cells").get<std::vector<std::uint8_t>>();
        } catch (const nlohmann::json::exception& error) {
          throw_error(ErrorCode::kFormat, "scene parameter 'charuco': {}", error.what());
        }
        return true;
      }
      if (key == "inner_corners_x") p.inner_corners_x = r.integer(key, v);
      else if (key == "inner_corners_y") p.inner_corners_y = r.integer(key, v);
      else if (key == "square_m") p.square = r.number(key, v);
      else if (key == "margin_m") p.margin = r.number(key, v);
      else if (key == "albedo_dark") p.albedo_dark = r.number(key, v);
      else if (key == "albedo_light") p.albedo_light = r.number(key, v);
      else return false;
      return true;
    });
    return make_chessboard_scene(p);
  }
  return make_scene(name);  // throws, naming the known scenes
}

}  // namespace sls::sim
