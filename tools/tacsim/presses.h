#pragma once
#include <cstdint>
#include <string>

namespace pg {

struct PressesArgs {
  std::string mesh;         // the object's mesh
  std::string out;          // the scene file to write
  std::string sensor;       // a preset name (default "digit")
  std::string sensor_file;  // or a sensor configuration file
  std::string name;         // the object's name (default: the mesh file's stem)
  int frames = 50;
  // Each press's depth range [m]; 0: not given, then 0.75 of the gel's max_indentation_m (1.5 mm
  // on the presets) and a fifth of the deepest (0.3 mm).
  double min_depth_m = 0, max_depth_m = 0;
  double scale = 1.0;
  std::uint64_t seed = 1;
  bool quiet = false;  // no progress line
};

// Writes a scene of independent random presses of a mesh into a sensor's gel, one per frame
// (pg::random_presses): training and validation data for a learned-normals model.
int run_presses(const PressesArgs& args);

}  // namespace pg
