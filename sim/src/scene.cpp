#include "pg/sim/scene.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "pg/core/dataset.h"
#include "pg/core/json_fields.h"
#include "pg/core/numbers.h"
#include "pg/core/se3.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

std::string resolve(const std::string& base_dir, const std::string& p) {
  const fs::path path(p);
  return (path.is_absolute() ? path : fs::path(base_dir) / path).lexically_normal().string();
}

// {"position": [m], "rpy": [rad]} or {"position": [m], "quaternion": [x, y, z, w]}.
SE3 read_pose(const nlohmann::json& j, const std::string& where) {
  JsonFields f(j, where);
  const Eigen::Vector3d position = f.position("position", Eigen::Vector3d::Zero());
  SE3 pose = SE3::Translation(position);
  if (f.has("rpy") && f.has("quaternion")) {
    throw InputError(where + ": give either rpy or quaternion, not both");
  }
  if (f.has("rpy")) pose = pose_from_position_rpy(position, f.required_rpy("rpy"));
  if (f.has("quaternion")) pose = SE3(f.required<Eigen::Quaterniond>("quaternion"), position);
  f.finish();
  return pose;
}

// An object's or sensor's motion: "pose" (constant) or "trajectory" with "waypoints" or "poses".
Trajectory read_motion(JsonFields& f) {
  if (f.has("pose") && f.has("trajectory")) {
    throw InputError(f.field("pose") + ": give either pose or trajectory, not both");
  }
  if (f.has("pose")) return Trajectory::constant(read_pose(f.at("pose"), f.field("pose")));
  if (!f.has("trajectory")) return Trajectory();
  JsonFields t(f.at("trajectory"), f.field("trajectory"));
  if (t.has("waypoints") == t.has("poses")) {
    throw InputError(f.field("trajectory") + ": expected exactly one of waypoints or poses");
  }
  if (t.has("poses")) {
    const auto& arr = t.at("poses");
    if (!arr.is_array() || arr.empty()) {
      throw InputError(t.field("poses") + ": expected a non-empty array of poses");
    }
    std::vector<SE3> poses;
    for (std::size_t i = 0; i < arr.size(); ++i) {
      poses.push_back(read_pose(arr[i], t.field("poses") + "[" + std::to_string(i) + "]"));
    }
    t.finish();
    return Trajectory::from_poses(poses);
  }
  const auto& arr = t.at("waypoints");
  if (!arr.is_array() || arr.empty()) {
    throw InputError(t.field("waypoints") + ": expected a non-empty array of waypoints");
  }
  std::vector<Waypoint> waypoints;
  for (std::size_t i = 0; i < arr.size(); ++i) {
    const std::string where = t.field("waypoints") + "[" + std::to_string(i) + "]";
    JsonFields w(arr[i], where);
    Waypoint wp;
    wp.frame = w.required<int>("frame");
    wp.position_m = w.position("position", Eigen::Vector3d::Zero());
    wp.rpy_rad = w.rpy("rpy", Eigen::Vector3d::Zero());
    w.finish();
    if (!waypoints.empty() && wp.frame <= waypoints.back().frame) {
      throw InputError(where + ".frame: frames must increase strictly (" +
                       std::to_string(wp.frame) + " after " +
                       std::to_string(waypoints.back().frame) + ")");
    }
    // Between two waypoints the orientation turns the shorter way (slerp): a turn about one
    // axis of more than pi in one step, written with an angle beyond +-pi (a spin as yaw 0 ->
    // 6.28), turns less than it says, or not at all. (Steps that change several angles go from
    // one orientation to another, and angles within +-pi that wrap, 3.11 -> -3.12, mean the
    // short way.)
    if (!waypoints.empty()) {
      const Eigen::Vector3d step = wp.rpy_rad - waypoints.back().rpy_rad;
      // (pi written to a few digits, 3.141593, is not beyond it.)
      const double wrap = kPi + 1e-3;
      const bool beyond_pi = wp.rpy_rad.cwiseAbs().maxCoeff() > wrap ||
                             waypoints.back().rpy_rad.cwiseAbs().maxCoeff() > wrap;
      const int changed = int((step.array().abs() > 1e-9).count());
      if (changed == 1 && beyond_pi && step.cwiseAbs().maxCoeff() > kPi) {
        const double turn = rotation_distance(
            pose_from_position_rpy(Eigen::Vector3d::Zero(), wp.rpy_rad),
            pose_from_position_rpy(Eigen::Vector3d::Zero(), waypoints.back().rpy_rad));
        std::fprintf(stderr,
                     "warning: %s.rpy: one angle changes by %.3g rad since the waypoint before, "
                     "more than pi: between waypoints the object turns the shorter way from one "
                     "orientation to the other (here %.2f rad); for a longer turn, add waypoints "
                     "less than pi apart\n",
                     where.c_str(), step.cwiseAbs().maxCoeff(), turn);
      }
    }
    waypoints.push_back(wp);
  }
  t.finish();
  return Trajectory::from_waypoints(waypoints);
}

// A scene with several sensors writes each one's dataset to OUT/<sensor name>/, so the name must
// be one plain folder name: no separator, not "." or "..", nothing that escapes OUT.
void check_folder_name(const std::string& name, const std::string& where) {
  const auto allowed = [](char c) {  // ASCII only, whatever the locale
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-' || c == '.';
  };
  if (name.empty() || name == "." || name == ".." ||
      !std::all_of(name.begin(), name.end(), allowed)) {
    throw InputError(where + ": '" + excerpt(name) +
                     "' is not a plain folder name (letters, digits, '_', '-', '.'; not '.' or "
                     "'..'): it names the sensor's output folder");
  }
  if (name == kSensorIndexFile) {
    throw InputError(where + ": '" + name +
                     "' is the render's index of its sensors (written next " +
                     "to their folders); name the sensor otherwise");
  }
  if (name == "dataset.json") {  // a folder of that name made OUT read as a broken dataset
    throw InputError(where + ": '" + name +
                     "' is a dataset's description file; a folder of that name next to the "
                     "sensors' folders would make them read as one broken dataset; name the "
                     "sensor otherwise");
  }
}

SceneSensor read_sensor(const nlohmann::json& j, const std::string& where,
                        const std::string& base_dir, int index) {
  JsonFields f(j, where);
  SceneSensor s;
  s.name = f.optional<std::string>("name", "sensor" + std::to_string(index));
  check_folder_name(s.name, f.field("name"));
  if (f.has("sensor") && f.has("sensor_file")) {
    throw InputError(where + ": give either sensor or sensor_file, not both");
  }
  if (f.has("sensor_file")) {
    const std::string file = f.required<std::string>("sensor_file");
    if (file.empty()) {
      throw InputError(f.field("sensor_file") + ": empty; give the sensor file's path");
    }
    try {
      s.model = load_sensor_file(resolve(base_dir, file));
    } catch (const InputError& e) {  // the sensor file's own error, and where the scene names it
      throw InputError(f.field("sensor_file") + ": " + e.what());
    }
  } else if (f.has("sensor") && f.at("sensor").is_string()) {
    try {
      s.model = sensor_preset(f.required<std::string>("sensor"));
    } catch (const InputError& e) {
      throw InputError(f.field("sensor") + ": " + e.what());
    }
  } else if (f.has("sensor")) {
    s.model = sensor_from_json(f.at("sensor"), f.field("sensor"));
  } else {
    s.model = sensor_preset("digit");
  }
  s.T_world_sensor = read_motion(f);
  f.finish();
  return s;
}

// `sensors`: the scene's, for "held_by".
SceneObject read_object(const nlohmann::json& j, const std::string& where,
                        const std::string& base_dir, int index,
                        const std::vector<SceneSensor>& sensors) {
  JsonFields f(j, where);
  SceneObject o;
  o.name = f.optional<std::string>("name", "object" + std::to_string(index));
  if (o.name.empty()) throw InputError(f.field("name") + ": empty; give the object a name");
  const std::string mesh = f.required<std::string>("mesh");
  if (mesh.empty()) throw InputError(f.field("mesh") + ": empty; give the mesh file's path");
  o.mesh_path = resolve(base_dir, mesh);
  o.scale = f.number_in("scale", 1e-6, 1e6, 1.0);
  o.T_world_object = read_motion(f);
  if (f.has("held_by")) {
    // Its pose or trajectory is then in that sensor's frame, and it moves with the sensor.
    const std::string holder = f.required<std::string>("held_by");
    const auto it = std::find_if(sensors.begin(), sensors.end(),
                                 [&](const SceneSensor& s) { return s.name == holder; });
    if (it == sensors.end()) {
      throw InputError(f.field("held_by") + ": no sensor is named '" + holder + "'");
    }
    o.T_world_object = o.T_world_object.carried_by(it->T_world_sensor);
  }
  f.finish();
  return o;
}

template <typename Read>
auto read_array(JsonFields& f, const std::string& key, Read read) {
  const auto& arr = f.at(key);
  if (!arr.is_array() || arr.empty()) {
    throw InputError(f.field(key) + ": expected a non-empty array");
  }
  std::vector<decltype(read(arr[0], std::string(), 0))> out;
  for (std::size_t i = 0; i < arr.size(); ++i) {
    out.push_back(read(arr[i], f.field(key) + "[" + std::to_string(i) + "]", int(i)));
  }
  return out;
}

// Each entry's name once: `field` is the array's ("scene.json: sensors"), `key` its key.
template <typename Entry>
void check_unique_names(const std::vector<Entry>& entries, const std::string& field,
                        const std::string& key, const std::string& why) {
  for (std::size_t i = 1; i < entries.size(); ++i) {
    for (std::size_t k = 0; k < i; ++k) {
      if (entries[i].name == entries[k].name) {
        throw InputError(field + "[" + std::to_string(i) + "].name: '" + entries[i].name +
                         "' is also " + key + "[" + std::to_string(k) + "]'s name; " + why);
      }
    }
  }
}

}  // namespace

Scene scene_from_json(const nlohmann::json& j, const std::string& name,
                      const std::string& base_dir) {
  JsonFields f(j, name);
  Scene scene;
  scene.path = name;
  scene.frames = f.required<int>("frames");
  if (scene.frames < 1 || scene.frames > 10000000) {
    throw InputError(f.field("frames") + ": must be in [1, 10000000]");
  }
  scene.fps = f.number_in("fps", 1e-3, 1e6, scene.fps);
  scene.sensors =
      read_array(f, "sensors", [&](const nlohmann::json& s, const std::string& w, int i) {
        return read_sensor(s, w, base_dir, i);
      });
  check_unique_names(scene.sensors, f.field("sensors"), "sensors",
                     "each sensor writes to its own folder OUT/<name>/");
  scene.objects =
      read_array(f, "objects", [&](const nlohmann::json& o, const std::string& w, int i) {
        return read_object(o, w, base_dir, i, scene.sensors);
      });
  check_unique_names(scene.objects, f.field("objects"), "objects",
                     "tracked_object and the dataset name the object by it");
  if (f.has("tracked_object")) {
    const std::string tracked = f.required<std::string>("tracked_object");
    const auto it = std::find_if(scene.objects.begin(), scene.objects.end(),
                                 [&](const SceneObject& o) { return o.name == tracked; });
    if (it == scene.objects.end()) {
      throw InputError(f.field("tracked_object") + ": no object is named '" + tracked + "'");
    }
    scene.tracked_object = int(it - scene.objects.begin());
  }
  // Read above, so of the expected shapes.
  const auto longest_motion = [&](const char* list, std::size_t count) {
    for (std::size_t i = 0; i < count; ++i) {
      const nlohmann::json& item = f.at(list)[i];
      if (!item.contains("trajectory")) continue;
      const nlohmann::json& t = item["trajectory"];
      const bool listed = t.contains("poses");
      const std::int64_t n = listed ? std::int64_t(t["poses"].size())
                                    : t["waypoints"].back()["frame"].get<std::int64_t>();
      if (n > scene.motion_frames) {
        scene.motion_frames = n;
        scene.motion_field = f.field(list) + "[" + std::to_string(i) + "].trajectory." +
                             (listed ? "poses" : "waypoints");
      }
    }
  };
  longest_motion("sensors", scene.sensors.size());
  longest_motion("objects", scene.objects.size());
  if (f.has("render")) {
    JsonFields r(f.at("render"), f.field("render"));
    auto& render = scene.render;
    render.outputs = r.optional<std::vector<std::string>>("outputs", render.outputs);
    check_output_names(render.outputs, r.field("outputs"));
    render.noise = r.optional<bool>("noise", render.noise);
    render.shadows = r.optional<bool>("shadows", render.shadows);
    const std::string bg = r.optional<std::string>("background", "synthetic");
    render.background = names_synthetic_background(bg) ? "" : resolve(base_dir, bg);
    render.seed_given = r.has("seed");
    render.seed = r.optional<std::uint64_t>("seed", render.seed);
    r.finish();
  }
  f.finish();
  return scene;
}

Scene load_scene(const std::string& path) {
  const std::string base = fs::path(path).parent_path().string();
  const nlohmann::json j = parse_json_file(path);
  check_json_file_kind(j, path, JsonFileKind::kScene);
  return scene_from_json(j, path, base.empty() ? "." : base);
}

}  // namespace pg
