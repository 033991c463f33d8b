#pragma once
// The vision-based tactile sensor: camera, gel, lights, noise. Values are SI (metres, radians).
// Sensor frame S: origin at the centre of the undeformed gel surface, +z out of the sensor toward
// the touched object, +x image right, +y image down. The camera sits on the -z axis.
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "pg/core/se3.h"

namespace pg {

// The image sizes a sensor may have, each side [px]: a sensor file's, a CLI override's, a model's.
constexpr int kMinImageSide = 8, kMaxImageSide = 8192;

// Pinhole camera; pixel (i, j) has its centre at u = i, v = j (OpenCV convention).
struct CameraModel {
  int width = 120;   // [px]
  int height = 160;  // [px]
  double fx = 0, fy = 0, cx = 0, cy = 0;  // [px]
  double near_m = 0.001;      // near clipping plane [m]
  double distance_m = 0.022;  // camera centre behind the gel centre, on the -z axis [m]

  static CameraModel from_vertical_fov(int width, int height, double fov_y_rad,
                                       double distance_m, double near_m);
  // The same camera at another image size (intrinsics scaled with the image).
  CameraModel resized(int new_width, int new_height) const;

  SE3 T_sensor_camera() const { return SE3::Translation({0.0, 0.0, -distance_m}); }
  // Ray direction in the camera frame through pixel coordinates (u, v), with z = 1.
  Eigen::Vector3d ray(double u, double v) const { return {(u - cx) / fx, (v - cy) / fy, 1.0}; }
  Eigen::Vector2d project(const Eigen::Vector3d& p_camera) const {
    return {fx * p_camera.x() / p_camera.z() + cx, fy * p_camera.y() / p_camera.z() + cy};
  }
  // Image scale at the gel's centre [px / m]; its inverse is a pixel's size there.
  double px_per_m_at_gel() const { return fy / distance_m; }
};

// How the gel's surface moves around a contact. With `enabled` false the gel is rigid (TACTO's
// z-buffer model: the gel takes the object's shape exactly where it is penetrated, nothing else).
// With it on, the coated gel surface cannot bend more sharply than bend_radius_m: it takes the
// object's shape inside the contact, and rounds the edge where the contact ends, leaving the
// object tangentially and curving back to the undeformed gel (sink-in around the contact).
struct ElasticModel {
  bool enabled = true;
  double bend_radius_m = 0.0005;  // smallest radius of curvature of the free gel surface [m]
  // The coating smooths away surface detail finer than this (Gaussian sigma) [m]; it also keeps
  // the pixel staircase of steep contact walls out of the normals.
  double smoothing_m = 0.00005;
};

struct GelModel {
  double width_m = 0.020;   // along x [m]
  double height_m = 0.030;  // along y [m]
  // Convex profile: a sphere cap of radius profile_radius_m, rescaled so that the corners sit
  // sag_m behind the centre (TACTO's DIGIT gel: R = 0.1 m rescaled to 5 mm).
  double sag_m = 0.005;
  double profile_radius_m = 0.1;
  // Deepest indentation the gel takes [m]; deeper penetration is clamped (and counted).
  double max_indentation_m = 0.002;
  ElasticModel elastic;

  // z of the undeformed gel surface in S at (x, y) [m]; 0 at the centre, -sag_m at the corners.
  double surface_z(double x, double y) const;
};

struct PointLight {
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  // in S [m]
  Eigen::Vector3d color = Eigen::Vector3d::Ones();       // linear RGB in [0, 1]
  double intensity = 1.0;
};

// How the gel's reflective coating turns light into pixel values. The lights sit behind the gel
// and light the coating from the camera's side: Blinn-Phong diffuse + specular, each light's
// contribution scaled by (d0 / d)^2 with d0 its distance to the gel centre.
struct ShadingModel {
  double ambient = 0.15;   // light every point gets regardless of its normal
  double diffuse = 0.75;
  double specular = 0.25;
  int shininess = 16;      // Blinn-Phong exponent
  double exposure = 0.9;   // scales the summed light to the 0-1 pixel range
  // TACTO-style blending with a real background image: out = bg + blur(sim - sim_bg) * gain,
  // with a Gaussian blur of this standard deviation on the gel [m].
  double background_gain = 0.5;
  double background_blur_m = 0.0002;
};

struct NoiseModel {
  double sigma = 7.0;  // Gaussian pixel noise on the 0-255 scale, after blending
};

struct SensorModel {
  std::string name = "digit";
  CameraModel camera;
  GelModel gel;
  std::vector<PointLight> lights;
  ShadingModel shading;
  NoiseModel noise;
  // The lights were measured on a real sensor (patchgraph fit-sensor on its ball presses sets it;
  // a sensor file's "lights_measured": true), not a preset's design: the shading's inverse then
  // describes a recording made with them.
  bool lights_measured = false;
};

// Built-in presets: "digit" (120x160, the paper's simulation), "digit_240x320" (the real DIGIT
// stream), "gelsight_mini" (240x320, about 0.065 mm/px). Throws InputError for other names.
SensorModel sensor_preset(const std::string& name);
std::vector<std::string> sensor_preset_names();

// JSON form: {"preset": NAME, "width": W, "height": H, "camera": {...}, "gel": {...},
// "lights": [...], "noise": {...}}; every key optional, each overrides the preset (default
// "digit"). `where` names the file/field in error messages. Unknown keys and out-of-range values
// throw InputError naming the key.
SensorModel sensor_from_json(const nlohmann::json& j, const std::string& where);
nlohmann::json sensor_to_json(const SensorModel& sensor);
SensorModel load_sensor_file(const std::string& path);
// Throws InputError, naming `where` and the field, unless `sensor` is one a sensor file could
// give (the ranges and geometry sensor_from_json checks): for a model set in C++, which the
// renderer and the tracker's front end check as they are built (a camera left at fx = 0 had
// crashed the renderer).
void check_sensor_model(const SensorModel& sensor, const std::string& where);

}  // namespace pg
