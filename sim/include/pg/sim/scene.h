#pragma once
// Scene files: sensors, objects, trajectories and render options (JSON; schema in README.md).
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "pg/core/sensor.h"
#include "pg/core/trajectory.h"

namespace pg {

struct SceneSensor {
  std::string name;
  SensorModel model;
  Trajectory T_world_sensor;  // by default the world is the first sensor's frame
};

struct SceneObject {
  std::string name;
  std::string mesh_path;  // resolved against the scene file's folder
  double scale = 1.0;
  Trajectory T_world_object;
};

// The words that name the renderer's own (synthetic) background where an image path could go:
// a scene's render.background and the tools' --background.
inline bool names_synthetic_background(const std::string& background) {
  return background == "synthetic" || background == "none";
}

struct SceneRender {
  std::vector<std::string> outputs = {"color", "normal", "depth", "mask"};
  bool noise = true;
  bool shadows = false;
  std::string background;  // "" = synthetic (the sensor's own shading of the undeformed gel)
  std::uint64_t seed = 0;
  bool seed_given = false;  // render.seed in the file (0 otherwise, as every such scene's)
};

struct Scene {
  std::string path;  // the scene file
  int frames = 1;
  double fps = 60.0;
  std::vector<SceneSensor> sensors;
  std::vector<SceneObject> objects;
  int tracked_object = 0;  // index into objects: the object whose pose goes into poses.csv
  SceneRender render;
  // The longest motion the file gives and its field (0 and "" without trajectories): a pose
  // list's length, or the last waypoint's frame (which the scenes put at `frames`, the motion's
  // end one past the last frame rendered). Longer than `frames`, the rest is never rendered.
  std::int64_t motion_frames = 0;
  std::string motion_field;
};

// Throws InputError naming the file, line/column (malformed JSON) or field (missing, wrong type,
// unknown key, out of range).
Scene load_scene(const std::string& path);
// The same for JSON already parsed; relative mesh/background paths resolve against `base_dir`.
Scene scene_from_json(const nlohmann::json& j, const std::string& name,
                      const std::string& base_dir);

}  // namespace pg
