#pragma once
// patchgraph fit-sensor: a sensor's lights measured from labelled presses (pg/sim/shading_fit.h),
// written as a sensor file for `recording --sensor-file`, `tacsim render` and the shading's
// inverse.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace pg {

struct FitSensorArgs {
  std::vector<std::string> datasets;  // labelled presses: colour images and normals
  std::vector<std::string> val;       // held-out labelled presses, read through both sensors
  std::string out;                    // the fitted sensor file
  std::string sensor;                 // the start: a preset ...
  std::string sensor_file;            // ... or a sensor file; default the datasets' own
  int iterations = 100;
  bool quiet = false;
};

CLI::App* add_fit_sensor_command(CLI::App& app, FitSensorArgs& args);
int run_fit_sensor(const FitSensorArgs& args);

}  // namespace pg
