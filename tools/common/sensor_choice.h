#pragma once
// The sensor a command's --sensor PRESET / --sensor-file FILE options name.
#include <string>

#include "cli_main.h"
#include "pg/core/error.h"
#include "pg/core/sensor.h"

namespace pg {

// The preset --sensor names; an unknown name is a usage error naming the option.
inline SensorModel preset_option(const std::string& preset) {
  try {
    return sensor_preset(preset);
  } catch (const InputError& e) {
    throw UsageError(std::string("--sensor: ") + e.what());
  }
}

// The preset (default "digit") or the file's sensor (a file that is missing or malformed is an
// InputError naming it); both given is a usage error.
inline SensorModel chosen_sensor(const std::string& preset, const std::string& file) {
  if (!preset.empty() && !file.empty()) throw UsageError("--sensor and --sensor-file: give one");
  if (!file.empty()) return load_sensor_file(file);
  return preset_option(preset.empty() ? "digit" : preset);
}

}  // namespace pg
