#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "../common/test_support.h"
#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "pg/core/json_fields.h"
#include "pg/core/sensor.h"

namespace pg {
namespace {

using testing_support::expect_input_error;

TEST(SensorPreset, DigitMatchesDesignDefaults) {
  const SensorModel s = sensor_preset("digit");
  EXPECT_EQ(s.camera.width, 120);
  EXPECT_EQ(s.camera.height, 160);
  // Vertical FOV of 60 degrees: the half-height subtends 30 degrees.
  EXPECT_NEAR(std::atan(0.5 * 160 / s.camera.fy), kPi / 6, 1e-12);
  EXPECT_DOUBLE_EQ(s.camera.distance_m, 0.022);
  EXPECT_DOUBLE_EQ(s.camera.near_m, 0.001);
  EXPECT_DOUBLE_EQ(s.gel.width_m, 0.020);
  EXPECT_DOUBLE_EQ(s.gel.height_m, 0.030);
  EXPECT_NEAR(s.gel.surface_z(0, 0), 0.0, 1e-15);
  EXPECT_NEAR(s.gel.surface_z(0.010, 0.015), -0.005, 1e-12);  // corner sag
  EXPECT_LT(s.gel.surface_z(0.005, 0.0), 0.0);
  ASSERT_EQ(s.lights.size(), 3u);
  for (const auto& l : s.lights) {
    EXPECT_NEAR(l.position_m.head<2>().norm(), 0.020, 1e-12);
    EXPECT_NEAR(l.position_m.z(), -0.017, 1e-12);
    EXPECT_DOUBLE_EQ(l.intensity, 1.0);
  }
  EXPECT_EQ(s.lights[0].color, Eigen::Vector3d(1, 0, 0));
  EXPECT_DOUBLE_EQ(s.noise.sigma, 7.0);
}

TEST(SensorPreset, Digit240x320IsTheSameCameraAtTwiceTheResolution) {
  const SensorModel lo = sensor_preset("digit"), hi = sensor_preset("digit_240x320");
  EXPECT_EQ(hi.camera.width, 240);
  EXPECT_EQ(hi.camera.height, 320);
  EXPECT_NEAR(hi.camera.fy, 2 * lo.camera.fy, 1e-9);
  // The same point projects to the same place in normalised image coordinates.
  const Eigen::Vector3d p(0.003, -0.004, 0.021);
  const Eigen::Vector2d a = lo.camera.project(p), b = hi.camera.project(p);
  EXPECT_NEAR((a.x() + 0.5) * 2, b.x() + 0.5, 1e-9);
  EXPECT_NEAR((a.y() + 0.5) * 2, b.y() + 0.5, 1e-9);
  EXPECT_NEAR((lo.camera.resized(240, 320).fx), hi.camera.fx, 1e-9);
}

TEST(SensorPreset, GelsightMiniScale) {
  const SensorModel s = sensor_preset("gelsight_mini");
  EXPECT_EQ(s.camera.width, 240);
  EXPECT_EQ(s.camera.height, 320);
  const double mm_per_px = 1000.0 * s.camera.distance_m / s.camera.fx;
  EXPECT_NEAR(mm_per_px, 0.065, 0.002);
}

// How far a camera sees past its gel: nowhere on the presets; a wider field of view of the DIGIT
// past its 20 mm width first (its image is 0.75 as wide as tall, its gel 0.67), by what the
// pixel rays' hits on the gel, continued past its edges at the edge's height, say. A very wide
// image sees past the gel's sides only as far as the rays reach at that height (it had read 643
// mm along x, and 148 mm along y, where the view stays within the gel).
TEST(SensorPreset, TheCameraSeesPastTheGelOnlyWithAWiderView) {
  for (const auto& name : sensor_preset_names()) {
    const SensorModel s = sensor_preset(name);
    EXPECT_EQ(view_beyond_gel(s.camera, s.gel), Eigen::Vector2d::Zero()) << name;
  }
  SensorModel wide = sensor_preset("digit");
  const double fov = 1.4;
  wide.camera.fy = (wide.camera.height / 2.0) / std::tan(fov / 2);
  wide.camera.fx = wide.camera.fy;
  const Eigen::Vector2d beyond = view_beyond_gel(wide.camera, wide.gel);
  // The farthest along x: the first column's rays near the middle row, where the gel sags least.
  // Past the edge the gel is continued at the edge's height there: that ray meets the plane
  // z = surface_z(-width / 2, y at the hit).
  const Eigen::Vector3d d = wide.camera.ray(0, 79);
  double lo = 0, hi = 2 * wide.camera.distance_m;
  for (int it = 0; it < 100; ++it) {
    const double t = 0.5 * (lo + hi);
    const bool before =
        t - wide.camera.distance_m < wide.gel.surface_z(-wide.gel.width_m / 2, d.y() * t);
    (before ? lo : hi) = t;
  }
  EXPECT_NEAR(beyond.x(), std::abs(d.x()) * lo - wide.gel.width_m / 2, 1e-7);
  EXPECT_GT(beyond.x(), 2e-3);
  EXPECT_LT(beyond.y(), beyond.x());
  // 640 x 160 px at the DIGIT's 1.05 rad vertical view: about 50 mm to either side at the gel,
  // and within its 30 mm along y.
  SensorModel strip = sensor_preset("digit");
  strip.camera.width = 640;
  strip.camera.cx = 319.5;
  const Eigen::Vector2d strip_beyond = view_beyond_gel(strip.camera, strip.gel);
  // (The first column's ray through the middle row, at the height of the gel's edge there.)
  const double half_view =
      std::abs(strip.camera.ray(0, 80).x()) *
      (strip.camera.distance_m + strip.gel.surface_z(-strip.gel.width_m / 2, 0.0));
  EXPECT_NEAR(strip_beyond.x(), half_view - strip.gel.width_m / 2, 1e-5);
  EXPECT_LT(strip_beyond.x(), 0.05);
  EXPECT_EQ(strip_beyond.y(), 0.0);
}

TEST(SensorPreset, UnknownNameListsKnownOnes) {
  expect_input_error([] { sensor_preset("gelsight9000"); }, {"gelsight9000", "digit"});
}

// Every field set off its preset's value comes back: compared field by field with the model
// written, not with a second writing (a field the writer leaves out would be missing from both).
TEST(SensorConfig, JsonRoundTripIsExact) {
  SensorModel s = sensor_preset("gelsight_mini");
  s.name = "my_sensor";
  s.camera.fx = 301.5;
  s.camera.fy = 302.25;
  s.camera.cx = 118.75;
  s.camera.cy = 161.125;
  s.camera.near_m = 0.0015;
  s.camera.distance_m = 0.0235;
  s.gel.width_m = 0.0185;
  s.gel.height_m = 0.0235;
  s.gel.sag_m = 0.0035;
  s.gel.profile_radius_m = 0.085;
  s.gel.max_indentation_m = 0.0017;
  s.gel.elastic.enabled = false;
  s.gel.elastic.bend_radius_m = 0.0025;
  s.gel.elastic.smoothing_m = 0.00007;
  s.lights[1].position_m = {0.001, -0.002, -0.0125};
  s.lights[1].color = {0.25, 0.5, 0.75};
  s.lights[1].intensity = 0.5;
  s.shading.ambient = 0.125;
  s.shading.diffuse = 0.625;
  s.shading.specular = 0.375;
  s.shading.shininess = 9;
  s.shading.exposure = 0.8125;
  s.shading.background_gain = 0.4375;
  s.shading.background_blur_m = 0.00031;
  s.noise.sigma = 3.5;
  s.lights_measured = true;
  const SensorModel b = sensor_from_json(sensor_to_json(s), "test");
  EXPECT_EQ(b.name, s.name);
  EXPECT_TRUE(b.lights_measured);
  // Written only where set: a preset's reads as it always did.
  EXPECT_FALSE(sensor_to_json(sensor_preset("digit")).contains("lights_measured"));
  EXPECT_FALSE(sensor_from_json(sensor_to_json(sensor_preset("digit")), "test").lights_measured);
  EXPECT_EQ(b.camera.width, s.camera.width);
  EXPECT_EQ(b.camera.height, s.camera.height);
  EXPECT_EQ(b.camera.fx, s.camera.fx);
  EXPECT_EQ(b.camera.fy, s.camera.fy);
  EXPECT_EQ(b.camera.cx, s.camera.cx);
  EXPECT_EQ(b.camera.cy, s.camera.cy);
  EXPECT_EQ(b.camera.near_m, s.camera.near_m);
  EXPECT_EQ(b.camera.distance_m, s.camera.distance_m);
  EXPECT_EQ(b.gel.width_m, s.gel.width_m);
  EXPECT_EQ(b.gel.height_m, s.gel.height_m);
  EXPECT_EQ(b.gel.sag_m, s.gel.sag_m);
  EXPECT_EQ(b.gel.profile_radius_m, s.gel.profile_radius_m);
  EXPECT_EQ(b.gel.max_indentation_m, s.gel.max_indentation_m);
  EXPECT_EQ(b.gel.elastic.enabled, s.gel.elastic.enabled);
  EXPECT_EQ(b.gel.elastic.bend_radius_m, s.gel.elastic.bend_radius_m);
  EXPECT_EQ(b.gel.elastic.smoothing_m, s.gel.elastic.smoothing_m);
  ASSERT_EQ(b.lights.size(), s.lights.size());
  for (std::size_t i = 0; i < s.lights.size(); ++i) {
    EXPECT_EQ(b.lights[i].position_m, s.lights[i].position_m) << "light " << i;
    EXPECT_EQ(b.lights[i].color, s.lights[i].color) << "light " << i;
    EXPECT_EQ(b.lights[i].intensity, s.lights[i].intensity) << "light " << i;
  }
  EXPECT_EQ(b.shading.ambient, s.shading.ambient);
  EXPECT_EQ(b.shading.diffuse, s.shading.diffuse);
  EXPECT_EQ(b.shading.specular, s.shading.specular);
  EXPECT_EQ(b.shading.shininess, s.shading.shininess);
  EXPECT_EQ(b.shading.exposure, s.shading.exposure);
  EXPECT_EQ(b.shading.background_gain, s.shading.background_gain);
  EXPECT_EQ(b.shading.background_blur_m, s.shading.background_blur_m);
  EXPECT_EQ(b.noise.sigma, s.noise.sigma);
}

TEST(SensorConfig, OverridesOnAPreset) {
  const auto j = nlohmann::json::parse(R"({"preset": "digit", "width": 240, "height": 320,
      "gel": {"max_indentation_m": 0.001, "elastic": {"enabled": false}},
      "noise": {"sigma": 0}})");
  const SensorModel s = sensor_from_json(j, "cfg.json");
  EXPECT_EQ(s.camera.width, 240);
  EXPECT_NEAR(s.camera.fy, sensor_preset("digit_240x320").camera.fy, 1e-9);
  EXPECT_DOUBLE_EQ(s.gel.max_indentation_m, 0.001);
  EXPECT_FALSE(s.gel.elastic.enabled);
  EXPECT_DOUBLE_EQ(s.noise.sigma, 0.0);
}

TEST(SensorConfig, ExplicitIntrinsics) {
  const auto j =
      nlohmann::json::parse(R"({"camera": {"fx": 100, "fy": 110, "cx": 59.5, "cy": 79.5}})");
  const SensorModel s = sensor_from_json(j, "cfg.json");
  EXPECT_DOUBLE_EQ(s.camera.fx, 100);
  EXPECT_DOUBLE_EQ(s.camera.fy, 110);
}

TEST(SensorConfig, ErrorsNameTheKey) {
  auto parse = [](const char* text) {
    return [text] { sensor_from_json(nlohmann::json::parse(text), "cfg.json"); };
  };
  expect_input_error(parse(R"({"colour": 1})"), {"cfg.json", "colour", "unknown key"});
  expect_input_error(parse(R"({"gel": {"sag": 1}})"), {"gel.sag", "unknown key"});
  expect_input_error(parse(R"({"gel": {"width_m": -1}})"), {"gel.width_m", "out of range"});
  expect_input_error(parse(R"({"gel": {"width_m": "wide"}})"), {"gel.width_m", "a number"});
  expect_input_error(parse(R"({"camera": {"fov_y_rad": 4}})"), {"camera.fov_y_rad", "range"});
  expect_input_error(parse(R"({"camera": {"fx": 100}})"), {"camera.fy", "missing"});
  expect_input_error(parse(R"({"width": 2})"), {"width"});
  // Another shape of image than the preset's stretches its resized pixels: refused, unless the
  // file gives the new camera; the same shape at another size is fine.
  expect_input_error(
      parse(R"({"preset": "gelsight_mini", "width": 320, "height": 240})"),
      {"width and height: 320x240 px", "0.563 times as wide as tall", "camera.fov_y_rad"});
  EXPECT_NO_THROW(parse(R"({"width": 320, "height": 240, "camera": {"fov_y_rad": 0.8}})")());
  EXPECT_NO_THROW(parse(R"({"width": 60, "height": 80})")());
  expect_input_error(parse(R"({"noise": {"sigma": 1000}})"), {"noise.sigma"});
  expect_input_error(parse(R"({"lights": []})"), {"lights"});
  expect_input_error(parse(R"({"lights": [{"color": [1,0,0]}]})"),
                     {"lights[0].position_m", "missing"});
  expect_input_error(parse(R"({"lights": [{"position_m": [0,0], "color": [1,0,0]}]})"),
                     {"lights[0].position_m", "3 numbers"});
  expect_input_error(parse(R"({"lights": [{"position_m": [0,0,-0.01], "color": [2,0,0]}]})"),
                     {"lights[0].color"});
  // On the gel's surface plane or beyond it, a light shines on the coating from behind.
  expect_input_error(parse(R"({"lights": [{"position_m": [0,0,0]}]})"),
                     {"lights[0].position_m", "behind the gel"});
  expect_input_error(parse(R"({"lights": [{"position_m": [0.01,0,0.01]}]})"),
                     {"lights[0].position_m", "z = 0.010000"});
  expect_input_error(parse(R"({"preset": "nope"})"), {"preset", "nope"});
  expect_input_error(parse(R"({"gel": {"elastic": {"bend_radius_m": 2}}})"),
                     {"gel.elastic.bend_radius_m"});
  expect_input_error(parse(R"([1, 2])"), {"cfg.json", "an object"});
  expect_input_error(parse(R"({"lights": [{"position_m": [0, 1e300, 0]}]})"),
                     {"lights[0].position_m", "out of range", "1000 m"});
  // The geometry the renderer needs, named by the field that breaks it: the near plane before
  // the camera's distance (the error had blamed a sag of 0), the deepest press in front of it
  // (one deeper had rendered as no contact, or the gel behind the camera), the lights between
  // the camera and the curved gel (one behind the camera got shadows of a coarse march; one in
  // front of the gel's curved surface rendered without a word).
  expect_input_error(parse(R"({"camera": {"distance_m": 0.0005}, "gel": {"sag_m": 0}})"),
                     {"camera.near_m (1 mm) must be less than camera.distance_m (0.5 mm)"});
  // The same with the near plane given, as a sensor file written out in full gives it (it had
  // read "camera.near_m: value 0.001 is out of range [1e-06, 0.0005]", blaming the default).
  expect_input_error(
      parse(R"({"camera": {"distance_m": 0.0005, "near_m": 0.001}, "gel": {"sag_m": 0}})"),
      {"camera.near_m (1 mm) must be less than camera.distance_m (0.5 mm)"});
  expect_input_error(parse(R"({"camera": {"distance_m": 0.005}, "gel": {"sag_m": 0,
      "max_indentation_m": 0.01}, "lights": [{"position_m": [0, 0, -0.003]}]})"),
                     {"gel.max_indentation_m (10 mm): a press that deep would reach the camera's "
                      "near plane (camera.distance_m - camera.near_m - gel.sag_m = 4 mm)"});
  expect_input_error(parse(R"({"lights": [{"position_m": [0.022, 0, -0.023]}]})"),
                     {"lights[0].position_m: z = -23 mm is at or behind the camera (z = -22 mm)"});
  expect_input_error(parse(R"({"lights": [{"position_m": [0, 0.0129, -0.001]}]})"),
                     {"lights[0].position_m: z = -1 mm is on or beyond the gel's surface"});
  // Behind the undeformed surface but within the reach of a press (2 mm), which would pass it.
  expect_input_error(parse(R"({"lights": [{"position_m": [0, 0, -0.0015]}]})"),
                     {"lights[0].position_m: z = -1.5 mm is on or beyond the gel's surface "
                      "pressed to gel.max_indentation_m, at z = -2 mm there"});
  expect_input_error(
      parse(R"({"camera": {"distance_m": 0.01}})"),
      {"lights[0].position_m (the preset's): z = -17 mm is at or behind the camera"});
}

// A strongly curved gel seen at a grazing angle: every pixel's undeformed gel point lies on the
// gel's surface, the first along its ray (the fixed-point iteration had swung there and left
// normals up to 79 deg off at the image's corners).
TEST(SensorConfig, AStronglyCurvedGelIsFoundAlongEveryRay) {
  const SensorModel s = sensor_from_json(
      nlohmann::json::parse(R"({"gel": {"sag_m": 0.02, "max_indentation_m": 0.0005},
          "lights": [{"position_m": [0.005, 0, -0.01]}]})"),
      "cfg");
  double worst = 0.0;
  for (int y = 0; y < s.camera.height; ++y) {
    for (int x = 0; x < s.camera.width; ++x) {
      const Eigen::Vector3d p = undeformed_gel_point(s.camera, s.gel, x, y);
      worst = std::max(worst, std::abs(p.z() - s.gel.surface_z(p.x(), p.y())));
      // The ray is in front of the surface (on the camera's side, z below it) until then.
      const Eigen::Vector3d d = s.camera.ray(x, y);
      const double t_hit = p.z() + s.camera.distance_m;
      for (double t = s.camera.near_m; t < t_hit - 1e-6; t += 1e-4) {
        ASSERT_LT(t - s.camera.distance_m, s.gel.surface_z(d.x() * t, d.y() * t) + 1e-12)
            << "pixel " << x << ", " << y << " at depth " << t;
      }
    }
  }
  EXPECT_LT(worst, 1e-9);
}

TEST(SensorConfig, WrongTypedPresetNamesTheFieldOnce) {
  try {
    sensor_from_json(nlohmann::json::parse(R"({"preset": 5})"), "cfg.json");
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "cfg.json: preset: expected a string, got a number");
  }
}

TEST(JsonFile, MalformedJsonReportsLineAndColumn) {
  expect_input_error([] { parse_json_text("{\n  \"a\": 1,\n  \"b\": ]\n}", "x.json"); },
                     {"x.json:3:", "malformed JSON"});
  expect_input_error([] { parse_json_file("/nonexistent/dir/s.json"); },
                     {"/nonexistent/dir/s.json", "cannot read"});
}

TEST(JsonFile, NumberOverflowAndDirectoriesNameTheFile) {
  expect_input_error([] { parse_json_text("{\"a\": [1, -2e308, 3]}", "x.json"); },
                     {"x.json: malformed JSON: number overflow parsing '-2e308'"});
  try {
    parse_json_text("{\"a\": 1e" + std::string(5000, '9') + "}", "x.json");
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_LT(std::string(e.what()).size(), 200u) << "the number is quoted whole";
  }
  expect_input_error([] { parse_json_file("/"); }, {"/: is a directory, not a JSON file"});
  expect_input_error([] { parse_json_file("/dev/zero"); }, {"/dev/zero: is not a regular file"});
}

// nlohmann keeps a repeated key's last value without a word: a scene's second "frames" won. The
// error names the key by its path, as the fields' own errors do (it had named the key alone).
TEST(JsonFile, AKeyGivenTwiceInOneObjectIsRefused) {
  expect_input_error([] { parse_json_text(R"({"frames": 3, "fps": 30, "frames": 2})", "s.json"); },
                     {"s.json: frames: given twice in one object"});
  expect_input_error(
      [] { parse_json_text(R"({"a": {"x": 1}, "b": [{"y": 1, "y": 2}]})", "s.json"); },
      {"s.json: b[0].y: given twice"});
  expect_input_error(
      [] {
        parse_json_text(R"({"objects": [{"name": "a"}, {"trajectory": {"waypoints": [
                          {"frame": 0, "rpy": [0, 0, 0]},
                          {"frame": 9, "rpy": [0, 0, 0], "position": [0, 0, 0], "rpy": [1, 0, 0]}
                        ]}}]})",
                        "s.json");
      },
      {"s.json: objects[1].trajectory.waypoints[1].rpy: given twice"});
  // The same key in different objects is fine.
  const nlohmann::json j =
      parse_json_text(R"({"a": {"x": 1}, "b": {"x": 2}, "x": [{"x": 3}]})", "s.json");
  EXPECT_EQ(j["b"]["x"], 2);
  EXPECT_EQ(j["x"][0]["x"], 3);
}

// Which part of an array of numbers is wrong, not "expected an array of 3 numbers, got an array".
TEST(JsonFile, AWrongArrayOfNumbersSaysWhatIsWrong) {
  auto parse = [](const char* text) {
    return [text] { sensor_from_json(nlohmann::json::parse(text), "cfg.json"); };
  };
  expect_input_error(parse(R"({"lights": [{"position_m": [0, -0.01]}]})"),
                     {"lights[0].position_m: expected an array of 3 numbers, got 2 elements"});
  expect_input_error(
      parse(R"({"lights": [{"position_m": ["0", 0, -0.01]}]})"),
      {"lights[0].position_m: expected an array of 3 numbers, element 0 is a string"});
}

}  // namespace
}  // namespace pg
