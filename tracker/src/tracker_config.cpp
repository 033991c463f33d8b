#include "pg/tracker/tracker_config.h"

#include <initializer_list>
#include <nlohmann/json.hpp>
#include <utility>

#include "pg/core/json_fields.h"
#include "pg/core/numbers.h"

namespace pg {

namespace {

int int_in(JsonFields& f, const std::string& key, int lo, int hi, int fallback) {
  const int v = f.optional<int>(key, fallback);
  if (v < lo || v > hi) {
    throw InputError(f.field(key) + ": must be an integer in [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "]");
  }
  return v;
}

// An optional field naming one of `choices`; anything else is an InputError listing them.
template <class E>
void read_choice(JsonFields& f, const char* key, const char* what,
                 std::initializer_list<std::pair<const char*, E>> choices, E& out) {
  if (!f.has(key)) return;
  const std::string v = f.required<std::string>(key);
  std::string known;
  for (const auto& [name, value] : choices) {
    if (v == name) {
      out = value;
      return;
    }
    known += (known.empty() ? "" : ", ") + std::string(name);
  }
  throw InputError(f.field(key) + ": unknown " + what + " '" + v + "' (known: " + known + ")");
}

void read_depth(const nlohmann::json& j, const std::string& where, DepthOptions& d) {
  JsonFields f(j, where);
  d.min_normal_dot_ray = f.number_in("min_normal_dot_ray", 1e-3, 1.0, d.min_normal_dot_ray);
  d.disturbed_angle_rad = f.number_in("disturbed_angle_rad", 0.0, 1.0, d.disturbed_angle_rad);
  d.crop = f.optional<bool>("crop", d.crop);
  d.crop_margin_px = int_in(f, "crop_margin_px", 1, 1000, d.crop_margin_px);
  read_choice(f, "dst_backend", "backend",
              {{"real_fft", DstBackend::kRealFft}, {"fftw_r2r", DstBackend::kFftwR2r}},
              d.dst_backend);
  d.measure_fft_plans = f.optional<bool>("measure_fft_plans", d.measure_fft_plans);
  read_choice(f, "integration", "integration",
              {{"parity", DepthIntegration::kParity}, {"averaged", DepthIntegration::kAveraged}},
              d.integration);
  f.finish();
}

void read_mask(const nlohmann::json& j, const std::string& where, MaskOptions& m) {
  JsonFields f(j, where);
  m.min_depth_m = f.number_in("min_depth_m", 0.0, 0.01, m.min_depth_m);
  m.min_area_m2 = f.number_in("min_area_m2", 0.0, 1e-2, m.min_area_m2);
  m.relative_depth = f.number_in("relative_depth", 0.0, 1.0, m.relative_depth);
  m.core_relative_depth = f.number_in("core_relative_depth", 0.0, 1.0, m.core_relative_depth);
  f.finish();
}

void read_icp(const nlohmann::json& j, const std::string& where, IcpOptions& o) {
  JsonFields f(j, where);
  o.max_iterations = int_in(f, "max_iterations", 1, 10000, o.max_iterations);
  o.max_correspondence_m = f.number_in("max_correspondence_m", 1e-9, 1.0, o.max_correspondence_m);
  read_choice(f, "kernel", "robust kernel",
              {{"none", RobustKernel::kNone},
               {"huber", RobustKernel::kHuber},
               {"tukey", RobustKernel::kTukey}},
              o.kernel);
  o.kernel_scale_m = f.number_in("kernel_scale_m", 1e-9, 1.0, o.kernel_scale_m);
  o.symmetric = f.optional<bool>("symmetric", o.symmetric);
  o.max_normal_angle_rad = f.number_in("max_normal_angle_rad", 0.0, kPi, o.max_normal_angle_rad);
  o.convergence_translation_m =
      f.number_in("convergence_translation_m", 0.0, 1.0, o.convergence_translation_m);
  o.convergence_rotation_rad =
      f.number_in("convergence_rotation_rad", 0.0, 1.0, o.convergence_rotation_rad);
  o.cycle_extent_m = f.number_in("cycle_extent_m", 0.0, 1.0, o.cycle_extent_m);
  o.min_points = int_in(f, "min_points", 6, 100000000, o.min_points);
  o.voxel_size_m = f.number_in("voxel_size_m", 0.0, 1.0, o.voxel_size_m);
  if (o.voxel_size_m != 0.0 && o.voxel_size_m < 1e-6) {  // a micrometre: the grid's keys overflow
    throw InputError(f.field("voxel_size_m") + ": must be 0 (off) or from 1e-6 to 1 m");
  }
  o.coarse_points = int_in(f, "coarse_points", 0, 100000000, o.coarse_points);
  o.coarse_step_m = f.number_in("coarse_step_m", 0.0, 1.0, o.coarse_step_m);
  o.min_eigenvalue_ratio = f.number_in("min_eigenvalue_ratio", 0.0, 1.0, o.min_eigenvalue_ratio);
  o.flat_radius_m = f.number_in("flat_radius_m", 0.0, 1e3, o.flat_radius_m);
  o.min_residual_sigma_m = f.number_in("min_residual_sigma_m", 1e-12, 1.0, o.min_residual_sigma_m);
  f.finish();
}

}  // namespace

const char* to_string(RobustKernel kernel) {
  switch (kernel) {
    case RobustKernel::kNone:
      return "none";
    case RobustKernel::kHuber:
      return "huber";
    case RobustKernel::kTukey:
      return "tukey";
  }
  return "?";
}

TrackerConfig tracker_config_from_json(const nlohmann::json& j, const std::string& where,
                                       const TrackerConfig& base) {
  check_json_file_kind(j, where, JsonFileKind::kTrackerConfig);
  JsonFields f(j, where);
  TrackerConfig c = base;
  if (f.has("depth")) read_depth(f.at("depth"), f.field("depth"), c.depth);
  if (f.has("mask")) read_mask(f.at("mask"), f.field("mask"), c.mask);
  if (f.has("icp")) read_icp(f.at("icp"), f.field("icp"), c.icp);
  f.finish();
  return c;
}

TrackerConfig load_tracker_config(const std::string& path, const TrackerConfig& base) {
  return tracker_config_from_json(parse_json_file(path), path, base);
}

void check_tracker_config(const TrackerConfig& config, const std::string& where) {
  tracker_config_from_json(tracker_config_to_json(config), where);  // the reader's ranges
}

nlohmann::json tracker_config_to_json(const TrackerConfig& c) {
  return {
      {"depth",
       {{"min_normal_dot_ray", c.depth.min_normal_dot_ray},
        {"disturbed_angle_rad", c.depth.disturbed_angle_rad},
        {"crop", c.depth.crop},
        {"crop_margin_px", c.depth.crop_margin_px},
        {"dst_backend", c.depth.dst_backend == DstBackend::kRealFft ? "real_fft" : "fftw_r2r"},
        {"measure_fft_plans", c.depth.measure_fft_plans},
        {"integration", c.depth.integration == DepthIntegration::kParity ? "parity" : "averaged"}}},
      {"mask",
       {{"min_depth_m", c.mask.min_depth_m},
        {"min_area_m2", c.mask.min_area_m2},
        {"relative_depth", c.mask.relative_depth},
        {"core_relative_depth", c.mask.core_relative_depth}}},
      {"icp",
       {{"max_iterations", c.icp.max_iterations},
        {"max_correspondence_m", c.icp.max_correspondence_m},
        {"kernel", to_string(c.icp.kernel)},
        {"kernel_scale_m", c.icp.kernel_scale_m},
        {"symmetric", c.icp.symmetric},
        {"max_normal_angle_rad", c.icp.max_normal_angle_rad},
        {"convergence_translation_m", c.icp.convergence_translation_m},
        {"convergence_rotation_rad", c.icp.convergence_rotation_rad},
        {"cycle_extent_m", c.icp.cycle_extent_m},
        {"min_points", c.icp.min_points},
        {"voxel_size_m", c.icp.voxel_size_m},
        {"coarse_points", c.icp.coarse_points},
        {"coarse_step_m", c.icp.coarse_step_m},
        {"min_eigenvalue_ratio", c.icp.min_eigenvalue_ratio},
        {"flat_radius_m", c.icp.flat_radius_m},
        {"min_residual_sigma_m", c.icp.min_residual_sigma_m}}},
  };
}

}  // namespace pg
