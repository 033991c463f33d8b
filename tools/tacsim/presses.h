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
  double min_depth_m = 0.3e-3, max_depth_m = 1.5e-3;
  double scale = 1.0;
  std::uint64_t seed = 1;
};

// Writes a scene of independent random presses of a mesh into a sensor's gel, one per frame
// (pg::random_presses): training and validation data for a learned-normals model.
int run_presses(const PressesArgs& args);

}  // namespace pg
