#pragma once
#include <string>

namespace pg {

struct SensitivityArgs {
  std::string sensor;       // a preset name (default "digit")
  std::string sensor_file;  // or a sensor configuration file
  double sigma = -1;        // camera noise [levels]; below 0: the sensor's own
  double tilt_deg = 20;     // the tilted normals' angle from the undeformed gel's [deg]
  std::string out;          // optional map: the per-pixel bound [rad], EXR
};

// Prints how accurately one frame can tell the gel's normal at each pixel (pg::normal_bound):
// the no-contact image's clipping, and the bound's median, 90th percentile and blind share for the
// undeformed gel and for normals tilted by --tilt in eight directions.
int run_sensitivity(const SensitivityArgs& args);

}  // namespace pg
