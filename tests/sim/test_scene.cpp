// Scene files: every field parses, defaults, path resolution, error messages that name the file
// and the field, trajectories through the loader, and the committed scenes under scenes/.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "pg/core/error.h"
#include "pg/core/se3.h"
#include "pg/core/sensor.h"
#include "pg/sim/mesh.h"
#include "pg/sim/scene.h"
#include "pg/sim/scene_renderer.h"

namespace pg {
namespace {

namespace fs = std::filesystem;
using Eigen::Vector3d;
using nlohmann::json;

constexpr double kMm = 1e-3;

// A fresh folder under the system temp dir per test, removed with its contents afterwards.
class SceneFileTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const auto stamp = std::chrono::steady_clock::now().time_since_epoch().count();
    dir_ = fs::temp_directory_path() /
           ("pg_test_scene_" + std::string(info->name()) + "_" + std::to_string(stamp));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ignored;
    fs::remove_all(dir_, ignored);
  }

  std::string write(const std::string& relative, const std::string& text) {
    const fs::path path = dir_ / relative;
    fs::create_directories(path.parent_path());
    std::ofstream(path) << text;
    return path.string();
  }
  std::string write(const std::string& relative, const json& j) {
    return write(relative, j.dump(2));
  }
  std::string in_dir(const std::string& relative) const {
    return (dir_ / relative).lexically_normal().string();
  }

  fs::path dir_;
};

// The InputError message of loading `path`; fails the test if it loads.
std::string load_error(const std::string& path) {
  try {
    load_scene(path);
  } catch (const InputError& e) {
    return e.what();
  }
  ADD_FAILURE() << path << " loaded, but an InputError was expected";
  return "";
}

json minimal_scene() {
  return {{"frames", 3},
          {"sensors", json::array({json::object()})},
          {"objects", json::array({json{{"mesh", "m.glb"}}})}};
}

json waypoint(int frame, const Vector3d& position, const Vector3d& rpy) {
  return {{"frame", frame},
          {"position", {position.x(), position.y(), position.z()}},
          {"rpy", {rpy.x(), rpy.y(), rpy.z()}}};
}

void expect_near(const SE3& actual, const Vector3d& position, const Eigen::Quaterniond& rotation,
                 double tol = 1e-12) {
  EXPECT_LT((actual.translation() - position).norm(), tol)
      << "translation " << actual.translation().transpose() << ", expected "
      << position.transpose();
  EXPECT_LT(rotation_distance(actual, SE3(rotation, position)), tol);
}

// --------------------------------------------------------------------------- parsing

TEST_F(SceneFileTest, FullSceneParsesEveryField) {
  write("sensors/mini.json", json{{"preset", "gelsight_mini"}, {"noise", {{"sigma", 2.5}}}});
  const json scene = {
      {"frames", 12},
      {"fps", 30},
      {"sensors",
       {{{"name", "left"},
         {"sensor", "digit_240x320"},
         {"pose", {{"position", {0.01, 0, 0}}, {"rpy", {0, 0, kPi / 2}}}}},
        {{"name", "right"},
         {"sensor",
          {{"preset", "digit"},
           {"width", 60},
           {"height", 80},
           {"gel", {{"sag_m", 0.004}}},
           {"noise", {{"sigma", 3}}}}},
         {"pose", {{"position", {0, 0, 0.02}}, {"quaternion", {1, 0, 0, 0}}}}},
        {{"name", "from_file"},
         {"sensor_file", "sensors/mini.json"},
         {"trajectory", {{"poses", {{{"position", {0, 0, 0}}}, {{"position", {0, 0, 0.001}}}}}}}}}},
      {"objects",
       {{{"name", "cube"},
         {"mesh", "meshes/cube.glb"},
         {"scale", 0.5},
         {"trajectory",
          {{"waypoints",
            {waypoint(0, {0, 0, 0.01}, {0, 0, 0}), waypoint(10, {0.002, 0, 0.01}, {0.1, 0, 0})}}}}},
        {{"name", "ball"}, {"mesh", "/abs/ball.obj"}, {"pose", {{"position", {0, 0, 0.005}}}}}}},
      {"tracked_object", "ball"},
      {"render",
       {{"outputs", {"color", "mask"}},
        {"noise", false},
        {"shadows", true},
        {"background", "bg/real.png"},
        {"seed", 42}}}};
  const Scene s = load_scene(write("scene.json", scene));

  EXPECT_EQ(s.frames, 12);
  EXPECT_DOUBLE_EQ(s.fps, 30.0);
  ASSERT_EQ(s.sensors.size(), 3u);
  EXPECT_EQ(s.sensors[0].name, "left");
  EXPECT_EQ(s.sensors[0].model.camera.width, 240);
  EXPECT_EQ(s.sensors[0].model.camera.height, 320);
  expect_near(s.sensors[0].T_world_sensor.at(7), {0.01, 0, 0},
              quaternion_from_rpy({0, 0, kPi / 2}));
  EXPECT_EQ(s.sensors[1].model.camera.width, 60);
  EXPECT_EQ(s.sensors[1].model.camera.height, 80);
  EXPECT_DOUBLE_EQ(s.sensors[1].model.gel.sag_m, 0.004);
  EXPECT_DOUBLE_EQ(s.sensors[1].model.noise.sigma, 3.0);
  // quaternion [x, y, z, w] = [1, 0, 0, 0]: half a turn about x.
  expect_near(s.sensors[1].T_world_sensor.at(0), {0, 0, 0.02},
              Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Vector3d::UnitX())));
  EXPECT_EQ(s.sensors[2].model.name, "gelsight_mini");
  EXPECT_DOUBLE_EQ(s.sensors[2].model.noise.sigma, 2.5);
  EXPECT_DOUBLE_EQ(s.sensors[2].T_world_sensor.at(0).translation().z(), 0.0);
  EXPECT_DOUBLE_EQ(s.sensors[2].T_world_sensor.at(1).translation().z(), 0.001);
  EXPECT_DOUBLE_EQ(s.sensors[2].T_world_sensor.at(9).translation().z(), 0.001);  // holds last

  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[0].name, "cube");
  EXPECT_EQ(s.objects[0].mesh_path, in_dir("meshes/cube.glb"));
  EXPECT_DOUBLE_EQ(s.objects[0].scale, 0.5);
  expect_near(s.objects[0].T_world_object.at(10), {0.002, 0, 0.01},
              quaternion_from_rpy({0.1, 0, 0}));
  EXPECT_EQ(s.objects[1].mesh_path, "/abs/ball.obj");
  expect_near(s.objects[1].T_world_object.at(4), {0, 0, 0.005}, Eigen::Quaterniond::Identity());
  EXPECT_EQ(s.tracked_object, 1);

  EXPECT_EQ(s.render.outputs, (std::vector<std::string>{"color", "mask"}));
  EXPECT_FALSE(s.render.noise);
  EXPECT_TRUE(s.render.shadows);
  EXPECT_EQ(s.render.background, in_dir("bg/real.png"));
  EXPECT_EQ(s.render.seed, 42u);
}

TEST_F(SceneFileTest, DefaultsMakeTheFirstSensorTheWorld) {
  const Scene s = load_scene(write("scene.json", minimal_scene()));
  EXPECT_EQ(s.frames, 3);
  EXPECT_DOUBLE_EQ(s.fps, 60.0);
  ASSERT_EQ(s.sensors.size(), 1u);
  EXPECT_EQ(s.sensors[0].name, "sensor0");
  EXPECT_EQ(s.sensors[0].model.name, "digit");
  EXPECT_EQ(s.sensors[0].model.camera.width, 120);
  EXPECT_EQ(s.sensors[0].model.camera.height, 160);
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].name, "object0");
  EXPECT_DOUBLE_EQ(s.objects[0].scale, 1.0);
  for (int f : {0, 1, 2, 100}) {
    expect_near(s.sensors[0].T_world_sensor.at(f), Vector3d::Zero(),
                Eigen::Quaterniond::Identity());
    expect_near(s.objects[0].T_world_object.at(f), Vector3d::Zero(),
                Eigen::Quaterniond::Identity());
  }
  EXPECT_EQ(s.tracked_object, 0);
  EXPECT_EQ(s.render.outputs, (std::vector<std::string>{"color", "normal", "depth", "mask"}));
  EXPECT_TRUE(s.render.noise);
  EXPECT_FALSE(s.render.shadows);
  EXPECT_EQ(s.render.background, "");  // synthetic
  EXPECT_EQ(s.render.seed, 0u);

  json explicit_synthetic = minimal_scene();
  explicit_synthetic["render"] = {{"background", "synthetic"}};
  EXPECT_EQ(load_scene(write("synthetic.json", explicit_synthetic)).render.background, "");
}

TEST_F(SceneFileTest, RelativePathsResolveAgainstTheSceneFolder) {
  write("s.json", json{{"preset", "digit"}, {"width", 60}, {"height", 80}});
  json j = minimal_scene();
  j["sensors"][0] = {{"sensor_file", "../../s.json"}};
  j["objects"] = {{{"mesh", "../m/x.glb"}}, {{"mesh", "./y.obj"}}, {{"mesh", "z.stl"}}};
  j["render"] = {{"background", "../../bg.png"}};
  const Scene s = load_scene(write("a/b/scene.json", j));
  EXPECT_EQ(s.sensors[0].model.camera.width, 60);  // found dir/s.json
  EXPECT_EQ(s.objects[0].mesh_path, in_dir("a/m/x.glb"));
  EXPECT_EQ(s.objects[1].mesh_path, in_dir("a/b/y.obj"));
  EXPECT_EQ(s.objects[2].mesh_path, in_dir("a/b/z.stl"));
  EXPECT_EQ(s.render.background, in_dir("bg.png"));
}

// --------------------------------------------------------------------------- errors

TEST_F(SceneFileTest, MalformedJsonGivesFileLineAndColumn) {
  const std::string path =
      write("broken.json", std::string("{\n  \"frames\": 3,\n  \"sensors\": [,]\n}\n"));
  const std::string message = load_error(path);
  EXPECT_EQ(message.rfind(path + ":3:", 0), 0u) << message;
  EXPECT_NE(message.find("malformed JSON"), std::string::npos) << message;
}

TEST_F(SceneFileTest, ErrorsNameTheFileAndTheField) {
  struct Case {
    std::string name;
    std::function<void(json&)> edit;
    std::vector<std::string> expected;  // substrings of the message
  };
  const std::vector<Case> cases = {
      {"missing frames", [](json& j) { j.erase("frames"); }, {": frames", "missing"}},
      {"frames of the wrong type",
       [](json& j) { j["frames"] = "ten"; },
       {": frames", "expected an integer, got a string"}},
      {"frames not whole",
       [](json& j) { j["frames"] = 2.5; },
       {": frames", "expected an integer, got 2.5"}},
      {"frames beyond an int",
       [](json& j) { j["frames"] = 3000000000LL; },
       {": frames", "integer out of range (-2147483647 to 2147483647), got 3000000000"}},
      {"frames beyond an int, with an exponent",  // had read "expected an integer, got 1e+20"
       [](json& j) { j["frames"] = 1e20; },
       {": frames", "integer out of range (-2147483647 to 2147483647), got 1e+20"}},
      {"a seed with an exponent, beyond what a double holds exactly",
       [](json& j) { j["render"]["seed"] = 1e17; },
       {": render.seed", "got 1e+17; beyond 2^53", "write its digits"}},
      {"a seed of 2^64, past the largest",  // had read "write its digits", which it was
       [](json& j) { j["render"]["seed"] = 18446744073709551616.0; },
       {": render.seed", "integer out of range (0 to 18446744073709551615)"}},
      {"an empty mesh path",  // had read "scenes/: is a directory"
       [](json& j) { j["objects"][0]["mesh"] = ""; },
       {": objects[0].mesh: empty; give the mesh file's path"}},
      {"an empty object name",  // had read "tracked_object: no object is named ..."
       [](json& j) { j["objects"][0]["name"] = ""; },
       {": objects[0].name: empty"}},
      {"a scene given for a dataset's description",
       [](json& j) {
         j = {{"format", "patchgraph-dataset"}, {"frames", 3}};
       },
       {": is a dataset's description (dataset.json), not a scene file"}},
      {"a seed below zero",
       [](json& j) { j["render"]["seed"] = -3; },
       {": render.seed", "expected a non-negative integer, got -3"}},
      {"unknown top-level key", [](json& j) { j["colour"] = "red"; }, {": colour: unknown key"}},
      {"unknown nested key",
       [](json& j) { j["objects"][0]["colour"] = "red"; },
       {": objects[0].colour: unknown key"}},
      {"waypoint frames not increasing",
       [](json& j) {
         j["objects"][0]["trajectory"]["waypoints"] = {waypoint(5, {0, 0, 0}, {0, 0, 0}),
                                                       waypoint(5, {0, 0, 0}, {0, 0, 0})};
       },
       {"objects[0].trajectory.waypoints[1].frame", "increase"}},
      {"both pose and trajectory",
       [](json& j) {
         j["objects"][0]["pose"] = {{"position", {0, 0, 0}}};
         j["objects"][0]["trajectory"] = {{"poses", {{{"position", {0, 0, 0}}}}}};
       },
       {"objects[0].pose", "either pose or trajectory"}},
      {"unknown output",
       [](json& j) {
         j["render"] = {{"outputs", {"color", "rgb"}}};
       },
       {"render.outputs", "unknown output 'rgb'"}},
      {"an output that is not a string",
       [](json& j) {
         j["render"] = {{"outputs", {"color", {"mask"}}}};
       },
       {"render.outputs", "expected an array of strings, element 1 is an array"}},
      {"no output",
       [](json& j) {
         j["render"] = {{"outputs", json::array()}};
       },
       {"render.outputs",
        "empty; name at least one of color, normal, normal_png, depth, mask, points"}},
      {"unknown tracked object",
       [](json& j) { j["tracked_object"] = "ghost"; },
       {": tracked_object", "'ghost'"}},
      {"unknown sensor preset",
       [](json& j) { j["sensors"][0]["sensor"] = "digit9"; },
       {"sensors[0].sensor", "unknown sensor preset 'digit9'"}},
      {"zero quaternion",
       [](json& j) {
         j["objects"][0]["pose"] = {{"quaternion", {0, 0, 0, 0}}};
       },
       {"objects[0].pose.quaternion", "finite and non-zero"}},
      {"position beyond a kilometre",
       [](json& j) {
         j["objects"][0]["pose"] = {{"position", {0, 1.7e308, 0}}};
       },
       {"objects[0].pose.position", "out of range", "1000 m"}},
      {"waypoint position beyond a kilometre",
       [](json& j) {
         j["sensors"][0]["trajectory"]["waypoints"] = {waypoint(0, {0, 0, 0}, {0, 0, 0}),
                                                       waypoint(4, {-1e300, 0, 0}, {0, 0, 0})};
       },
       {"sensors[0].trajectory.waypoints[1].position", "out of range"}},
      {"rpy beyond a thousand radians",
       [](json& j) {
         j["objects"][0]["pose"] = {{"rpy", {0, 1e300, 0}}};
       },
       {"objects[0].pose.rpy", "out of range", "1000 rad"}},
      {"waypoint rpy beyond a thousand radians",
       [](json& j) {
         j["sensors"][0]["trajectory"]["waypoints"] = {waypoint(0, {0, 0, 0}, {0, 0, 0}),
                                                       waypoint(4, {0, 0, 0}, {0, 0, -2e3})};
       },
       {"sensors[0].trajectory.waypoints[1].rpy", "out of range"}},
      {"light position beyond a kilometre",
       [](json& j) {
         j["sensors"][0]["sensor"] = {{"lights", {{{"position_m", {0, 0, 2e3}}}}}};
       },
       {"sensors[0].sensor.lights[0].position_m", "out of range"}},
  };
  for (std::size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE(cases[i].name);
    json j = minimal_scene();
    cases[i].edit(j);
    const std::string path = write("case" + std::to_string(i) + ".json", j);
    const std::string message = load_error(path);
    EXPECT_EQ(message.rfind(path, 0), 0u) << "message does not start with the file: " << message;
    for (const std::string& part : cases[i].expected) {
      EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
    }
  }
}

// Each sensor of a multi-sensor scene writes its dataset to OUT/<name>/: a name that is not one
// plain folder name would write outside OUT, and two equal names into the same folder.
TEST_F(SceneFileTest, SensorNamesArePlainUniqueFolderNames) {
  for (const std::string bad : {"/tmp/x", "../..", "..", ".", "", "a/b", "a\\b", "two words"}) {
    SCOPED_TRACE("name '" + bad + "'");
    json j = minimal_scene();
    j["sensors"] = {{{"name", "ok"}}, {{"name", bad}}};
    const std::string path = write("bad_name.json", j);
    const std::string message = load_error(path);
    EXPECT_EQ(message.rfind(path + ": sensors[1].name: ", 0), 0u) << message;
    EXPECT_NE(message.find("not a plain folder name"), std::string::npos) << message;
  }
  json j = minimal_scene();
  j["sensors"] = {{{"name", "left"}}, {{"name", "right"}}, {{"name", "left"}}};
  std::string path = write("duplicate.json", j);
  std::string message = load_error(path);
  EXPECT_EQ(message.rfind(path + ": sensors[2].name: 'left' is also sensors[0]'s name", 0), 0u)
      << message;
  // The render's index of its sensors sits next to their folders.
  j["sensors"] = {{{"name", "left"}}, {{"name", "sensors.json"}}};
  path = write("index_name.json", j);
  message = load_error(path);
  EXPECT_EQ(message.rfind(path + ": sensors[1].name: 'sensors.json' is the render's index", 0), 0u)
      << message;
  j["sensors"] = {{{"name", "left"}}, {{"name", "dataset.json"}}};
  message = load_error(write("dataset_name.json", j));
  EXPECT_NE(message.find("sensors[1].name: 'dataset.json' is a dataset's description file"),
            std::string::npos)
      << message;
  // A default name ("sensor<i>") clashes like any other.
  j["sensors"] = {json::object(), {{"name", "sensor0"}}};
  message = load_error(write("default_clash.json", j));
  EXPECT_NE(message.find("sensors[1].name: 'sensor0' is also sensors[0]'s name"), std::string::npos)
      << message;

  j["sensors"] = {{{"name", "digit_top"}}, {{"name", "GelSight-Mini.2"}}, json::object()};
  const Scene s = load_scene(write("good.json", j));
  EXPECT_EQ(s.sensors[1].name, "GelSight-Mini.2");
  EXPECT_EQ(s.sensors[2].name, "sensor2");
}

// Two objects of one name made tracked_object pick the first without a word; an output listed
// twice was written twice and listed twice in dataset.json.
TEST_F(SceneFileTest, ObjectNamesAndOutputsAreEachGivenOnce) {
  json j = minimal_scene();
  j["objects"] = {{{"name", "a"}, {"mesh", "m.glb"}}, {{"name", "a"}, {"mesh", "n.glb"}}};
  std::string path = write("objects.json", j);
  std::string message = load_error(path);
  EXPECT_EQ(message.rfind(path + ": objects[1].name: 'a' is also objects[0]'s name", 0), 0u)
      << message;
  j = minimal_scene();
  j["render"] = {{"outputs", {"mask", "color", "mask"}}};
  path = write("outputs.json", j);
  message = load_error(path);
  EXPECT_EQ(message, path + ": render.outputs: output 'mask' is given twice");
}

// The norm of [1e200, 0, 0, 0] squared overflows; such a quaternion is still a rotation (half a
// turn about x) and must not be normalised to [0, 0, 0, 0].
// Between waypoints the orientation takes the shorter way: a spin written as one angle going
// beyond pi (yaw 0 -> 2 pi) turns less than it says, here not at all, and is warned about,
// naming the waypoint; an angle wrapping within +-pi (3.141593 -> -3.08: 0.06 rad, as the
// benchmark's scenes have it) and a step changing several angles are not.
TEST_F(SceneFileTest, ASpinBetweenTwoWaypointsIsWarnedAbout) {
  const auto warnings = [&](const Vector3d& from, const Vector3d& to) {
    json j = minimal_scene();
    j["frames"] = 11;
    j["objects"][0]["trajectory"] = {
        {"waypoints", {waypoint(0, Vector3d::Zero(), from), waypoint(10, Vector3d::Zero(), to)}}};
    const std::string path = write("spin.json", j);
    ::testing::internal::CaptureStderr();
    const Scene s = load_scene(path);
    const std::string err = ::testing::internal::GetCapturedStderr();
    return std::make_pair(err, rotation_distance(s.objects[0].T_world_object.at(0),
                                                 s.objects[0].T_world_object.at(5)));
  };
  const auto [spin, spin_turn] = warnings(Vector3d::Zero(), Vector3d(0, 0, 2 * kPi));
  EXPECT_LT(spin_turn, 1e-9) << "the shorter way: no turn";
  EXPECT_NE(spin.find("objects[0].trajectory.waypoints[1].rpy: one angle changes by 6.28 rad "
                      "since the waypoint before, more than pi"),
            std::string::npos)
      << spin;
  EXPECT_NE(spin.find("(here 0.00 rad)"), std::string::npos) << spin;
  EXPECT_EQ(warnings(Vector3d(3.141593, 0, 1.6), Vector3d(-3.08, 0, 1.6)).first, "");
  EXPECT_EQ(warnings(Vector3d::Zero(), Vector3d(3.5, 0.2, 0)).first, "");
}

TEST_F(SceneFileTest, QuaternionsOfAnyFiniteScaleAreNormalised) {
  json j = minimal_scene();
  j["objects"][0]["pose"] = {{"position", {0, 0, 0.01}}, {"quaternion", {1e200, 0, 0, 0}}};
  j["sensors"][0]["pose"] = {{"quaternion", {1e308, 0, 0, 1e308}}};
  j["objects"].push_back({{"mesh", "m.glb"}, {"pose", {{"quaternion", {0, 0, 3e-300, 0}}}}});
  const Scene s = load_scene(write("scene.json", j));
  expect_near(s.objects[0].T_world_object.at(0), {0, 0, 0.01},
              Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Vector3d::UnitX())));
  expect_near(s.sensors[0].T_world_sensor.at(0), Vector3d::Zero(),
              Eigen::Quaterniond(Eigen::AngleAxisd(kPi / 2, Vector3d::UnitX())));
  expect_near(s.objects[1].T_world_object.at(0), Vector3d::Zero(),
              Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Vector3d::UnitZ())));
  EXPECT_DOUBLE_EQ(s.objects[0].T_world_object.at(0).rotation().norm(), 1.0);
}

TEST_F(SceneFileTest, NumbersBeyondADoubleAndWrongTypedPresetsNameTheFileOnce) {
  std::string path = write("overflow.json", std::string(R"({"frames": 3, "fps": 1e400})"));
  std::string message = load_error(path);
  EXPECT_EQ(message.rfind(path + ": ", 0), 0u) << message;
  EXPECT_NE(message.find("number overflow parsing '1e400'"), std::string::npos) << message;
  EXPECT_EQ(message.find("[json.exception"), std::string::npos) << message;

  const std::string sensor = write("sensor.json", std::string(R"({"noise": {"sigma": 1e999}})"));
  json j = minimal_scene();
  j["sensors"][0] = {{"sensor_file", "sensor.json"}};
  const std::string scene = write("uses_sensor.json", j);
  message = load_error(scene);
  // Where the scene names the sensor file, then the sensor file's own error.
  EXPECT_EQ(message.rfind(scene + ": sensors[0].sensor_file: " + sensor + ": ", 0), 0u) << message;
  EXPECT_NE(message.find("number overflow"), std::string::npos) << message;

  // A scene given as the sensor file is named as one (it had read "fps: unknown key").
  j["sensors"][0] = {{"sensor_file", "uses_sensor.json"}};
  const std::string self = write("scene_as_sensor.json", j);
  message = load_error(self);
  EXPECT_NE(message.find("uses_sensor.json: is a scene file, not a sensor file"), std::string::npos)
      << message;

  j["sensors"][0] = {{"sensor", {{"preset", 5}}}};
  path = write("preset.json", j);
  message = load_error(path);
  EXPECT_EQ(message, path + ": sensors[0].sensor.preset: expected a string, got a number");
}

// --------------------------------------------------------------------------- trajectories

TEST_F(SceneFileTest, WaypointsInterpolateLinearlyAndBySlerp) {
  json j = minimal_scene();
  j["objects"][0]["trajectory"]["waypoints"] = {waypoint(0, {0, 0, 0.01}, {0, 0, 0}),
                                                waypoint(10, {0.01, 0, 0.01}, {0, 0, kPi / 2})};
  const Scene scene = load_scene(write("scene.json", j));
  const Trajectory& t = scene.objects[0].T_world_object;
  expect_near(t.at(5), {0.005, 0, 0.01}, quaternion_from_rpy({0, 0, kPi / 4}), 1e-12);
  expect_near(t.at(2), {0.002, 0, 0.01}, quaternion_from_rpy({0, 0, kPi / 10}), 1e-12);
  expect_near(t.at(-3), {0, 0, 0.01}, Eigen::Quaterniond::Identity());           // holds the first
  expect_near(t.at(20), {0.01, 0, 0.01}, quaternion_from_rpy({0, 0, kPi / 2}));  // and the last
}

// The longest motion a scene gives, for tacsim's warning when frames cuts it short (a list of
// 100 poses in a 10-frame scene had been rendered to its tenth without a word): a pose list's
// length, a waypoint list's last frame (the benchmark's scenes end theirs at `frames`).
TEST_F(SceneFileTest, TheLongestMotionIsKnown) {
  json j = minimal_scene();
  EXPECT_EQ(load_scene(write("still.json", j)).motion_frames, 0);
  j["objects"][0]["trajectory"]["waypoints"] = {waypoint(0, {0, 0, 0.01}, {0, 0, 0}),
                                                waypoint(3, {0.01, 0, 0.01}, {0, 0, 0})};
  Scene scene = load_scene(write("waypoints.json", j));
  EXPECT_EQ(scene.motion_frames, 3);
  EXPECT_EQ(scene.motion_field, scene.path + ": objects[0].trajectory.waypoints");
  j["sensors"][0]["trajectory"]["poses"] = json::array();
  for (int k = 0; k < 12; ++k) j["sensors"][0]["trajectory"]["poses"].push_back(json::object());
  scene = load_scene(write("poses.json", j));
  EXPECT_EQ(scene.motion_frames, 12);
  EXPECT_EQ(scene.motion_field, scene.path + ": sensors[0].trajectory.poses");
}

// Whole numbers written with a fraction (a generator that carries frame numbers as floats, numpy
// values) are those integers; they had been refused as "expected an integer, got a number".
TEST_F(SceneFileTest, WholeNumbersWrittenAsFloatsAreIntegers) {
  json j = minimal_scene();
  j["frames"] = 12.0;
  j["render"]["seed"] = 5.0;
  j["objects"][0]["trajectory"]["waypoints"] = {waypoint(0, {0, 0, 0.01}, {0, 0, 0}),
                                                waypoint(10, {0.01, 0, 0.01}, {0, 0, 0})};
  j["objects"][0]["trajectory"]["waypoints"][1]["frame"] = 10.0;
  const Scene scene = load_scene(write("scene.json", j));
  EXPECT_EQ(scene.frames, 12);
  EXPECT_EQ(scene.render.seed, 5u);
  expect_near(scene.objects[0].T_world_object.at(5), {0.005, 0, 0.01},
              Eigen::Quaterniond::Identity(), 1e-12);
  // An unsigned number beyond any int (2^64 - 1) had wrapped to -1 ("frames must increase
  // strictly (-1 after 0)").
  j["objects"][0]["trajectory"]["waypoints"][1]["frame"] = 18446744073709551615ull;
  const std::string message = load_error(write("huge_frame.json", j));
  EXPECT_NE(message.find("waypoints[1].frame: integer out of range"), std::string::npos) << message;
}

// An object "held_by" a sensor has its pose in that sensor's frame and moves with it; a name
// that is no sensor's is refused with the field.
TEST_F(SceneFileTest, AHeldObjectMovesWithItsSensor) {
  json j = minimal_scene();
  j["sensors"] = {json{{"name", "fixed"}},
                  json{{"name", "hand"},
                       {"trajectory",
                        {{"waypoints",
                          {waypoint(0, {0, 0, 0}, {0, 0, 0}),
                           waypoint(10, {0.1, 0.02, 0}, {0.3, 0, kPi / 2})}}}}}};
  j["objects"][0]["held_by"] = "hand";
  j["objects"][0]["trajectory"]["waypoints"] = {waypoint(0, {0, 0, 0.01}, {0, 0, 0}),
                                                waypoint(10, {0.002, 0, 0.01}, {0, 0.1, 0})};
  const Scene scene = load_scene(write("scene.json", j));
  const Trajectory& hand = scene.sensors[1].T_world_sensor;
  for (int frame : {-1, 0, 3, 7, 10, 12}) {
    const SE3 relative = hand.at(frame).inverse() * scene.objects[0].T_world_object.at(frame);
    const double s = std::clamp(frame / 10.0, 0.0, 1.0);
    expect_near(relative, {0.002 * s, 0, 0.01}, quaternion_from_rpy({0, 0.1 * s, 0}), 1e-12);
  }
  EXPECT_GT(scene.objects[0].T_world_object.at(10).translation().x(), 0.09) << "moved with it";
  j["objects"][0]["held_by"] = "hnad";
  EXPECT_NE(
      load_error(write("scene.json", j)).find("objects[0].held_by: no sensor is named 'hnad'"),
      std::string::npos);
}

// --------------------------------------------------------------------------- committed scenes

// Every .json under scenes/ is a scene, except sensor files in scenes/sensors/.
std::vector<fs::path> committed_scenes() {
  std::vector<fs::path> scenes;
  const fs::path root = fs::path(PG_SOURCE_DIR) / "scenes";
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    const fs::path rel = entry.path().lexically_relative(root);
    if (entry.is_regular_file() && entry.path().extension() == ".json" &&
        *rel.begin() != "sensors") {
      scenes.push_back(entry.path());
    }
  }
  std::sort(scenes.begin(), scenes.end());
  return scenes;
}

// Points on the mesh surface at most 0.25 mm apart: on the convex gel the middle of a long
// straight edge reaches deeper than the vertices at its ends.
const std::vector<Vector3d>& surface_points(const std::string& mesh_path) {
  static std::map<std::string, std::vector<Vector3d>> cache;
  auto it = cache.find(mesh_path);
  if (it != cache.end()) return it->second;
  const TriangleMesh mesh = load_mesh(mesh_path);
  std::vector<Vector3d> points;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Vector3d a = mesh.vertices[t[0]].cast<double>();
    const Vector3d ab = mesh.vertices[t[1]].cast<double>() - a;
    const Vector3d ac = mesh.vertices[t[2]].cast<double>() - a;
    const double longest = std::max({ab.norm(), ac.norm(), (ac - ab).norm()});
    const int n = std::max(1, int(std::ceil(longest / (0.25 * kMm))));
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) points.push_back(a + ab * i / n + ac * j / n);
    }
  }
  return cache.emplace(mesh_path, std::move(points)).first->second;
}

struct Contact {
  double depth = -std::numeric_limits<double>::infinity();  // max of surface_z - z [m]
  double max_abs_x = 0.0, max_abs_y = 0.0;                  // extent of the penetrating points [m]
};

Contact contact_in_sensor(const std::vector<Vector3d>& p_object, const SE3& T_sensor_object,
                          const GelModel& gel) {
  Contact c;
  for (const Vector3d& p : p_object) {
    const Vector3d q = T_sensor_object * p;
    if (q.z() >= 0.0) continue;  // surface_z <= 0: cannot penetrate
    const double depth = gel.surface_z(q.x(), q.y()) - q.z();
    c.depth = std::max(c.depth, depth);
    if (depth > 0.0) {
      c.max_abs_x = std::max(c.max_abs_x, std::abs(q.x()));
      c.max_abs_y = std::max(c.max_abs_y, std::abs(q.y()));
    }
  }
  return c;
}

TEST(CommittedScenes, AllLoadAndTheirMeshesExist) {
  const std::vector<fs::path> scenes = committed_scenes();
  ASSERT_GE(scenes.size(), 84u) << "expected the 80 benchmark scenes, default.json and examples";
  for (const fs::path& path : scenes) {
    SCOPED_TRACE(path.string());
    Scene s;
    ASSERT_NO_THROW(s = load_scene(path.string()));
    for (const SceneObject& o : s.objects) {
      EXPECT_TRUE(fs::is_regular_file(o.mesh_path)) << "missing mesh " << o.mesh_path;
    }
  }
  EXPECT_TRUE(fs::exists(fs::path(PG_SOURCE_DIR) / "scenes" / "default.json"));
}

// The paper's protocol: 20 sequences per simulated object, 300 frames each, one DIGIT (120x160)
// at the world origin, the object 0.2-2.0 mm into the gel inside the visible area (|x| < 8 mm,
// |y| < 10 mm) at every 10th frame.
TEST(CommittedScenes, BenchmarkHasTwentyContactSequencesPerObject) {
  const fs::path dir = fs::path(PG_SOURCE_DIR) / "scenes" / "benchmark";
  std::map<std::string, std::set<std::string>> by_object;
  for (const fs::path& path : committed_scenes()) {
    if (path.parent_path() != dir) continue;
    const std::string stem = path.stem().string();
    by_object[stem.substr(0, stem.rfind('_'))].insert(stem.substr(stem.rfind('_') + 1));
  }
  std::set<std::string> numbers;
  for (int i = 0; i < 20; ++i) numbers.insert((i < 10 ? "0" : "") + std::to_string(i));
  const std::vector<std::string> objects = {"cube", "sphere", "toy_brick", "toy_human"};
  ASSERT_EQ(by_object.size(), objects.size());
  for (const std::string& object : objects) EXPECT_EQ(by_object[object], numbers) << object;

  for (const std::string& object : objects) {
    for (const std::string& nn : numbers) {
      const std::string path = (dir / (object + "_" + nn + ".json")).string();
      SCOPED_TRACE(path);
      const Scene s = load_scene(path);
      EXPECT_EQ(s.frames, 300);
      ASSERT_EQ(s.sensors.size(), 1u);
      ASSERT_EQ(s.objects.size(), 1u);
      EXPECT_EQ(s.objects[s.tracked_object].name, object);
      const SensorModel& sensor = s.sensors[0].model;
      EXPECT_EQ(sensor.camera.width, 120);
      EXPECT_EQ(sensor.camera.height, 160);
      const std::vector<Vector3d>& points = surface_points(s.objects[0].mesh_path);
      for (int f = 0; f < s.frames; f += 10) {
        const SE3 T_sensor_object =
            s.sensors[0].T_world_sensor.at(f).inverse() * s.objects[0].T_world_object.at(f);
        const Contact c = contact_in_sensor(points, T_sensor_object, sensor.gel);
        EXPECT_GE(c.depth, 0.2 * kMm) << "frame " << f;
        EXPECT_LE(c.depth, 2.0 * kMm) << "frame " << f;
        EXPECT_LT(c.max_abs_x, 8.0 * kMm) << "frame " << f;
        EXPECT_LT(c.max_abs_y, 10.0 * kMm) << "frame " << f;
      }
    }
  }
}

// The disk-space check before a render (render_scene_to_dataset) rests on this estimate: one
// frame's files measured, times the frames. Against what whole renders write: one sensor with
// every output (the contact points vary from frame to frame), and two sensors.
TEST(SceneRendering, TheSizeEstimateIsNearWhatARenderWrites) {
  const fs::path dir = fs::temp_directory_path() / ("pg_size_" + std::to_string(::getpid()));
  for (const auto& [scene, outputs] : std::vector<std::pair<std::string, std::string>>{
           {"default.json", "color,normal,depth,mask,points"},
           {"examples/two_digits_regrasp.json", "color,normal"}}) {
    SCOPED_TRACE(scene);
    RenderOverrides overrides;
    std::stringstream list(outputs);
    for (std::string o; std::getline(list, o, ',');) overrides.outputs.push_back(o);
    const SceneRenderer renderer(load_scene(std::string(PG_SOURCE_DIR) + "/scenes/" + scene),
                                 overrides);
    fs::remove_all(dir);
    const RenderSummary summary = render_scene_to_dataset(renderer, dir.string());
    std::uintmax_t written = 0;
    for (const auto& entry : fs::recursive_directory_iterator(dir)) {
      if (entry.is_regular_file()) written += entry.file_size();
    }
    EXPECT_GT(written, 1'000'000u);
    EXPECT_EQ(summary.bytes_estimate, estimate_dataset_bytes(renderer));
    EXPECT_NEAR(double(summary.bytes_estimate) / double(written), 1.0, 0.1)
        << summary.bytes_estimate << " estimated, " << written << " written";
  }
  fs::remove_all(dir);
}

// The memory check before a render: as many frames at once as the threads and the available
// memory allow (kFrameBytesPerPixel a pixel over the sensors), none when one does not fit, all
// wanted when the system does not say.
TEST(SceneRendering, FramesInFlightFitTheAvailableMemory) {
  const std::uintmax_t px = 8192u * 8192u, frame = px * kFrameBytesPerPixel;  // 8 GB
  EXPECT_EQ(frames_in_flight(px, 300, 4, std::nullopt), 4);
  EXPECT_EQ(frames_in_flight(px, 2, 4, std::nullopt), 2);
  EXPECT_EQ(frames_in_flight(px, 300, 4, 10 * frame), 4);
  EXPECT_EQ(frames_in_flight(px, 300, 4, 2 * frame + 1), 2);
  EXPECT_EQ(frames_in_flight(px, 300, 4, frame), 1);
  EXPECT_EQ(frames_in_flight(px, 300, 4, frame - 1), 0);
  EXPECT_EQ(frames_in_flight(2 * px, 300, 4, 3 * frame), 1);  // two sensors' images a frame
  EXPECT_EQ(frames_in_flight(120 * 160, 300, 2, std::uintmax_t(1) << 30), 2);
  EXPECT_EQ(frames_in_flight(0, 300, 2, 0), 0);
}

}  // namespace
}  // namespace pg
