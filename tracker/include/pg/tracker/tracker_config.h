#pragma once
// The tracker config file: options of each measurement step, every key optional (defaults in the
// options structs), unknown keys rejected with the file and field named.
//
//   {
//     "depth": {"min_normal_dot_ray": 0.2, "disturbed_angle_rad": 0.005, "crop": true,
//               "crop_margin_px": 4, "dst_backend": "real_fft", "measure_fft_plans": false},
//     "mask":  {"min_depth_m": 1e-4, "min_area_m2": 5e-7, "relative_depth": 0.0,
//               "core_relative_depth": 0.2},
//     "icp":   {"max_iterations": 30, "max_correspondence_m": 1e-3, "kernel": "huber",
//               "kernel_scale_m": 1e-4, "convergence_translation_m": 1e-7,
//               "convergence_rotation_rad": 1e-6, "min_points": 20, "voxel_size_m": 0,
//               "min_eigenvalue_ratio": 5e-3, "flat_radius_m": 0, "min_residual_sigma_m": 1e-5}
//   }
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "pg/tracker/contact_cloud.h"
#include "pg/tracker/icp.h"

namespace pg {

struct TrackerConfig {
  DepthOptions depth;
  MaskOptions mask;
  IcpOptions icp;

  ContactCloudOptions contact_cloud() const { return {depth, mask, icp.min_eigenvalue_ratio}; }
};

// The keys of `j` set on top of `base` (the built-in defaults unless given): a key left out keeps
// base's value. `where` names the file in messages. Throws InputError naming the field for
// unknown keys, wrong types and out-of-range values.
TrackerConfig tracker_config_from_json(const nlohmann::json& j, const std::string& where,
                                       const TrackerConfig& base = TrackerConfig());
TrackerConfig load_tracker_config(const std::string& path,
                                  const TrackerConfig& base = TrackerConfig());
nlohmann::json tracker_config_to_json(const TrackerConfig& config);
// Throws InputError "WHERE: icp.max_iterations: ..." when a value of `config` is one a config
// file may not give (the file's ranges, NaN too): options set in C++ are checked as a file's.
void check_tracker_config(const TrackerConfig& config, const std::string& where);

const char* to_string(RobustKernel kernel);

}  // namespace pg
