#pragma once
// Per-pixel camera rays of a sensor and where they meet the undeformed gel: the geometry that
// turns an indentation image into points in the sensor frame S, computed from the sensor model
// alone (CameraModel + GelModel::surface_z), so it works for a real sensor too. The renderer
// (its GelGeometry adds per-frame culling bounds) and the tracker both start from these rays.
#include <Eigen/Core>
#include <vector>

#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg {

struct GelRays {
  int width = 0, height = 0;                // [px]
  double fx = 0, fy = 0;                    // focal lengths [px]
  double px_per_m = 0;                      // image scale at the gel centre [px / m]
  Eigen::Vector3f origin_sensor;            // camera centre in S [m]
  std::vector<Eigen::Vector3f> dir_sensor;  // per pixel ray, z = 1 (t is the camera depth) [-]
  std::vector<float> t_gel;                 // camera depth of the undeformed gel surface [m]

  int index(int x, int y) const { return y * width + x; }
  // The gel surface point seen through pixel i when indented by u [m] toward the camera:
  //   p_S = o + d_i (t_gel_i - u)
  Eigen::Vector3f point(int i, float u) const {
    return origin_sensor + dir_sensor[i] * (t_gel[i] - u);
  }
  // Area of one pixel on the gel at its centre [m^2].
  double pixel_area_m2() const { return 1.0 / (px_per_m * px_per_m); }
  // The sigma of the blur TACTO's blend gives the change (shading.background_blur_m) [px].
  double blend_blur_px(const ShadingModel& shading) const {
    return shading.background_blur_m * px_per_m;
  }
};

// Solves surface_z(d t) = t - distance for every pixel's ray (a fixed-point iteration; the gel's
// slope is small).
GelRays make_gel_rays(const CameraModel& camera, const GelModel& gel);

// Where the ray of pixel (x, y) meets the undeformed gel, in S [m] (make_gel_rays' point, in
// double precision, for the few pixels that need one).
Eigen::Vector3d undeformed_gel_point(const CameraModel& camera, const GelModel& gel, double x,
                                     double y);

// How far the image's pixel centres reach past the gel's own width_m x height_m on the undeformed
// gel, continued past its edges at the edge's height, along x and y [m] (0 where they stay within
// it). The renderer draws gel there, where a real sensor shows its housing.
Eigen::Vector2d view_beyond_gel(const CameraModel& camera, const GelModel& gel);

// The rigid gel (TACTO's model) indented by a sphere of `radius` [m] centred at `centre` in S:
// per pixel, how far in camera depth the sphere's near side lies in front of the undeformed
// gel [m] (width x height x 1), 0 where it does not. Its surface normals there point to the centre.
ImageF sphere_indentation(const GelRays& rays, const Eigen::Vector3d& centre, double radius);

// Unit normals (+z, out of the gel) of the gel indented by `indentation` (width x height x 1
// [m], toward the camera, as a dataset's depth image), width x height x 3, built like a rendered
// frame's: the cross product of the central differences of the surface points (clamped at the
// image border).
ImageF gel_normals(const GelRays& rays, const ImageF& indentation);
// The same for the undeformed gel: the reference when no no-contact frame is available.
ImageF undeformed_gel_normals(const GelRays& rays);

}  // namespace pg
