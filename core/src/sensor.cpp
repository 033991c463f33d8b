#include "pg/core/sensor.h"

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "pg/core/json_fields.h"
#include "pg/core/se3.h"

namespace pg {

namespace {

// Three coloured point lights on a circle in a plane behind the gel (TACTO's DIGIT layout), at
// angles from +x toward +y (image down). The colours follow a real DIGIT's background: red at
// the top, green to the lower right, blue to the lower left.
std::vector<PointLight> ring_lights(double radius_m, double z_m) {
  const double angles_deg[3] = {270.0, 30.0, 150.0};
  const Eigen::Vector3d colors[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  std::vector<PointLight> lights;
  for (int i = 0; i < 3; ++i) {
    const double a = angles_deg[i] * kPi / 180.0;
    lights.push_back({{radius_m * std::cos(a), radius_m * std::sin(a), z_m}, colors[i], 1.0});
  }
  return lights;
}

SensorModel digit(int width, int height) {
  SensorModel s;
  s.name = "digit";
  s.camera = CameraModel::from_vertical_fov(width, height, 60.0 * kPi / 180.0, 0.022, 0.001);
  s.lights = ring_lights(0.020, -0.017);
  return s;
}

SensorModel gelsight_mini() {
  SensorModel s;
  s.name = "gelsight_mini";
  // 320 px across about 20.8 mm at 15 mm: tan(fov_y / 2) = 10.4 / 15.
  s.camera = CameraModel::from_vertical_fov(240, 320, 2.0 * std::atan(10.4 / 15.0), 0.015, 0.001);
  s.gel.width_m = 0.018;
  s.gel.height_m = 0.024;
  s.gel.sag_m = 0.0005;  // a nearly flat gel
  s.gel.profile_radius_m = 0.1;
  s.gel.max_indentation_m = 0.0015;
  s.lights = ring_lights(0.015, -0.010);
  return s;
}

void read_camera(const nlohmann::json& j, const std::string& where, CameraModel& cam) {
  JsonFields f(j, where);
  cam.distance_m = f.number_in("distance_m", 1e-4, 1.0, cam.distance_m);
  // Below distance_m: checked with the rest of the geometry (sensor_from_json), in words that name
  // both, since a sensor file that gives both may have the wrong one in the distance.
  cam.near_m = f.number_in("near_m", 1e-6, 1.0, cam.near_m);
  if (f.has("fov_y_rad")) {
    const double fov = f.required_number_in("fov_y_rad", 1e-3, kPi - 1e-3);
    cam = CameraModel::from_vertical_fov(cam.width, cam.height, fov, cam.distance_m, cam.near_m);
  }
  const bool any_intrinsic = f.has("fx") || f.has("fy") || f.has("cx") || f.has("cy");
  if (any_intrinsic) {
    if (f.has("fov_y_rad")) {
      throw InputError(where + ": give either fov_y_rad or fx/fy/cx/cy, not both");
    }
    cam.fx = f.required_number_in("fx", 1e-3, 1e7);
    cam.fy = f.required_number_in("fy", 1e-3, 1e7);
    cam.cx = f.required_number_in("cx", -1e5, 1e5);
    cam.cy = f.required_number_in("cy", -1e5, 1e5);
  }
  f.finish();
}

void read_gel(const nlohmann::json& j, const std::string& where, GelModel& gel) {
  JsonFields f(j, where);
  gel.width_m = f.number_in("width_m", 1e-4, 1.0, gel.width_m);
  gel.height_m = f.number_in("height_m", 1e-4, 1.0, gel.height_m);
  gel.sag_m = f.number_in("sag_m", 0.0, 0.1, gel.sag_m);
  gel.profile_radius_m = f.number_in("profile_radius_m", 1e-4, 1e3, gel.profile_radius_m);
  gel.max_indentation_m = f.number_in("max_indentation_m", 1e-6, 0.05, gel.max_indentation_m);
  if (f.has("elastic")) {
    JsonFields e(f.at("elastic"), f.field("elastic"));
    gel.elastic.enabled = e.optional<bool>("enabled", gel.elastic.enabled);
    gel.elastic.bend_radius_m = e.number_in("bend_radius_m", 1e-6, 1.0, gel.elastic.bend_radius_m);
    gel.elastic.smoothing_m = e.number_in("smoothing_m", 0.0, 0.01, gel.elastic.smoothing_m);
    e.finish();
  }
  f.finish();
  const double corner_r = 0.5 * std::hypot(gel.width_m, gel.height_m);
  if (gel.sag_m > 0 && gel.profile_radius_m <= corner_r) {
    throw InputError(where + ".profile_radius_m: must exceed half the gel diagonal (" +
                     std::to_string(corner_r) + " m)");
  }
}

PointLight read_light(const nlohmann::json& j, const std::string& where) {
  JsonFields f(j, where);
  PointLight light;
  light.position_m = f.required_position("position_m");
  // The lights shine through the gel from the camera's side; one at or beyond the gel's surface
  // plane lights the coating from behind (an image black or nearly so, from no error at all).
  if (!(light.position_m.z() < 0.0)) {
    throw InputError(f.field("position_m") + ": z = " + std::to_string(light.position_m.z()) +
                     " m puts the light on or beyond the gel's surface; lights sit behind the "
                     "gel, on the camera's side (z < 0, e.g. the DIGIT's at -0.017)");
  }
  light.color = f.optional<Eigen::Vector3d>("color", light.color);
  if ((light.color.array() < 0.0).any() || (light.color.array() > 1.0).any()) {
    throw InputError(f.field("color") + ": components must be in [0, 1]");
  }
  light.intensity = f.number_in("intensity", 0.0, 1e3, light.intensity);
  f.finish();
  return light;
}

nlohmann::json vec_json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

}  // namespace

CameraModel CameraModel::from_vertical_fov(int width, int height, double fov_y_rad,
                                           double distance_m, double near_m) {
  CameraModel c;
  c.width = width;
  c.height = height;
  c.fy = 0.5 * height / std::tan(0.5 * fov_y_rad);
  c.fx = c.fy;
  c.cx = 0.5 * (width - 1);
  c.cy = 0.5 * (height - 1);
  c.distance_m = distance_m;
  c.near_m = near_m;
  return c;
}

CameraModel CameraModel::resized(int new_width, int new_height) const {
  CameraModel c = *this;
  const double sx = double(new_width) / width, sy = double(new_height) / height;
  c.width = new_width;
  c.height = new_height;
  c.fx = fx * sx;
  c.fy = fy * sy;
  // Pixel centres at integer coordinates: the image edge is at -0.5.
  c.cx = (cx + 0.5) * sx - 0.5;
  c.cy = (cy + 0.5) * sy - 0.5;
  return c;
}

double GelModel::surface_z(double x, double y) const {
  if (sag_m <= 0.0) return 0.0;
  const auto cap = [&](double r_sq) {
    return profile_radius_m - std::sqrt(std::max(0.0, profile_radius_m * profile_radius_m - r_sq));
  };
  const double corner_sq = 0.25 * (width_m * width_m + height_m * height_m);
  return -sag_m * cap(x * x + y * y) / cap(corner_sq);
}

std::vector<std::string> sensor_preset_names() {
  return {"digit", "digit_240x320", "gelsight_mini"};
}

SensorModel sensor_preset(const std::string& name) {
  if (name == "digit") return digit(120, 160);
  if (name == "digit_240x320") return digit(240, 320);
  if (name == "gelsight_mini") return gelsight_mini();
  std::string known;
  for (const auto& n : sensor_preset_names()) known += (known.empty() ? "" : ", ") + n;
  throw InputError("unknown sensor preset '" + name + "' (known: " + known + ")");
}

SensorModel sensor_from_json(const nlohmann::json& j, const std::string& where) {
  JsonFields f(j, where);
  SensorModel s;
  // Read outside the try: a wrong type's message already names the field; sensor_preset()'s not.
  const std::string preset = f.optional<std::string>("preset", "digit");
  try {
    s = sensor_preset(preset);
  } catch (const InputError& e) {
    throw InputError(f.field("preset") + ": " + e.what());
  }
  s.name = f.optional<std::string>("name", s.name);
  const double preset_aspect = s.camera.fx / s.camera.fy;
  if (f.has("width") || f.has("height")) {
    const int w = f.has("width") ? f.required<int>("width") : s.camera.width;
    const int h = f.has("height") ? f.required<int>("height") : s.camera.height;
    const std::string range = ": must be in [" + std::to_string(kMinImageSide) + ", " +
                              std::to_string(kMaxImageSide) + "] px";
    if (w < kMinImageSide || w > kMaxImageSide) throw InputError(f.field("width") + range);
    if (h < kMinImageSide || h > kMaxImageSide) throw InputError(f.field("height") + range);
    s.camera = s.camera.resized(w, h);
  }
  const bool own_intrinsics =
      f.has("camera") && f.at("camera").is_object() &&
      (f.at("camera").contains("fov_y_rad") || f.at("camera").contains("fx"));
  if ((f.has("width") || f.has("height")) && !own_intrinsics &&
      std::abs(s.camera.fx / s.camera.fy - preset_aspect) > 0.01 * preset_aspect) {
    // The intrinsics scale with each side: another shape of image stretches the pixels.
    char ratio[32];
    std::snprintf(ratio, sizeof ratio, "%.3g", s.camera.fy / s.camera.fx);
    throw InputError(f.field("width") + " and height: " + std::to_string(s.camera.width) + "x" +
                     std::to_string(s.camera.height) +
                     " px is not the shape of the preset's image, whose camera they resize: its "
                     "pixels would be " +
                     ratio +
                     " times as wide as tall; give camera.fov_y_rad (square pixels) or fx, fy, "
                     "cx, cy for the new image");
  }
  if (f.has("camera")) read_camera(f.at("camera"), f.field("camera"), s.camera);
  if (f.has("gel")) read_gel(f.at("gel"), f.field("gel"), s.gel);
  if (f.has("lights")) {
    const auto& arr = f.at("lights");
    if (!arr.is_array() || arr.empty()) {
      throw InputError(f.field("lights") + ": expected a non-empty array of lights");
    }
    s.lights.clear();
    for (std::size_t i = 0; i < arr.size(); ++i) {
      s.lights.push_back(read_light(arr[i], f.field("lights") + "[" + std::to_string(i) + "]"));
    }
  }
  if (f.has("shading")) {
    JsonFields sh(f.at("shading"), f.field("shading"));
    auto& m = s.shading;
    m.ambient = sh.number_in("ambient", 0.0, 10.0, m.ambient);
    m.diffuse = sh.number_in("diffuse", 0.0, 10.0, m.diffuse);
    m.specular = sh.number_in("specular", 0.0, 10.0, m.specular);
    m.shininess = sh.optional<int>("shininess", m.shininess);
    if (m.shininess < 1 || m.shininess > 256) {
      throw InputError(sh.field("shininess") + ": must be an integer in [1, 256]");
    }
    m.exposure = sh.number_in("exposure", 1e-3, 1e3, m.exposure);
    m.background_gain = sh.number_in("background_gain", 0.0, 10.0, m.background_gain);
    m.background_blur_m = sh.number_in("background_blur_m", 0.0, 0.01, m.background_blur_m);
    sh.finish();
  }
  s.lights_measured = f.optional<bool>("lights_measured", false);
  if (f.has("noise")) {
    JsonFields n(f.at("noise"), f.field("noise"));
    s.noise.sigma = n.number_in("sigma", 0.0, 255.0, s.noise.sigma);
    n.finish();
  }
  f.finish();
  // The geometry the renderer needs: the gel, pressed in as far as it goes, in front of the
  // camera's near plane, and the lights between the camera and the gel.
  const auto mm = [](double m) {
    char text[32];
    std::snprintf(text, sizeof text, "%.4g mm", 1e3 * m);
    return std::string(text);
  };
  const CameraModel& c = s.camera;
  if (c.near_m >= c.distance_m) {
    throw InputError(where + ": camera.near_m (" + mm(c.near_m) +
                     ") must be less than camera.distance_m (" + mm(c.distance_m) + ")");
  }
  const double room = c.distance_m - c.near_m;
  if (s.gel.sag_m >= room) {
    throw InputError(where + ": gel.sag_m (" + mm(s.gel.sag_m) +
                     ") puts the gel's corners in front of the camera's near plane "
                     "(camera.distance_m - camera.near_m = " +
                     mm(room) + ")");
  }
  if (s.gel.max_indentation_m >= room - s.gel.sag_m) {
    throw InputError(where + ": gel.max_indentation_m (" + mm(s.gel.max_indentation_m) +
                     "): a press that deep would reach the camera's near plane "
                     "(camera.distance_m - camera.near_m - gel.sag_m = " +
                     mm(room - s.gel.sag_m) + ")");
  }
  for (std::size_t i = 0; i < s.lights.size(); ++i) {
    const Eigen::Vector3d& p = s.lights[i].position_m;
    const std::string field = where + ": lights[" + std::to_string(i) + "].position_m" +
                              (f.has("lights") ? "" : " (the preset's)");
    if (!(p.z() > -c.distance_m)) {
      throw InputError(field + ": z = " + mm(p.z()) +
                       " is at or behind the camera (z = " + mm(-c.distance_m) +
                       "); lights sit between the camera and the gel (shadows are traced for "
                       "those)");
    }
    // The surface as the deepest press moves it: a light within that reach would be passed by
    // a press and light the coating from its far side (at coincidence, a division by zero).
    const double surface = s.gel.surface_z(p.x(), p.y());
    const double pressed = surface - s.gel.max_indentation_m;
    if (!(p.z() < pressed)) {
      throw InputError(field + ": z = " + mm(p.z()) +
                       " is on or beyond the gel's surface pressed to gel.max_indentation_m, at z "
                       "= " +
                       mm(pressed) + " there (the surface at " + mm(surface) +
                       "); lights sit between the camera and the gel");
    }
  }
  return s;
}

nlohmann::json sensor_to_json(const SensorModel& s) {
  nlohmann::json lights = nlohmann::json::array();
  for (const auto& l : s.lights) {
    lights.push_back({{"position_m", vec_json(l.position_m)},
                      {"color", vec_json(l.color)},
                      {"intensity", l.intensity}});
  }
  const auto& c = s.camera;
  const auto& g = s.gel;
  nlohmann::json j = {
      {"name", s.name},
      {"width", c.width},
      {"height", c.height},
      {"camera",
       {{"fx", c.fx},
        {"fy", c.fy},
        {"cx", c.cx},
        {"cy", c.cy},
        {"near_m", c.near_m},
        {"distance_m", c.distance_m}}},
      {"gel",
       {{"width_m", g.width_m},
        {"height_m", g.height_m},
        {"sag_m", g.sag_m},
        {"profile_radius_m", g.profile_radius_m},
        {"max_indentation_m", g.max_indentation_m},
        {"elastic",
         {{"enabled", g.elastic.enabled},
          {"bend_radius_m", g.elastic.bend_radius_m},
          {"smoothing_m", g.elastic.smoothing_m}}}}},
      {"lights", lights},
      {"shading",
       {{"ambient", s.shading.ambient},
        {"diffuse", s.shading.diffuse},
        {"specular", s.shading.specular},
        {"shininess", s.shading.shininess},
        {"exposure", s.shading.exposure},
        {"background_gain", s.shading.background_gain},
        {"background_blur_m", s.shading.background_blur_m}}},
      {"noise", {{"sigma", s.noise.sigma}}},
  };
  // Only where set: a preset's or render's sensor reads as it always did.
  if (s.lights_measured) j["lights_measured"] = true;
  return j;
}

void check_sensor_model(const SensorModel& sensor, const std::string& where) {
  // Through the reader's own checks, so that the ranges live in one place.
  sensor_from_json(sensor_to_json(sensor), where);
}

SensorModel load_sensor_file(const std::string& path) {
  const nlohmann::json j = parse_json_file(path);
  check_json_file_kind(j, path, JsonFileKind::kSensor);
  return sensor_from_json(j, path);
}

}  // namespace pg
