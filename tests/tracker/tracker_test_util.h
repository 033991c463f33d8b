#pragma once
// Shared helpers of the tracker geometry tests: analytic sphere frames, renders of the paper's
// objects, distances to meshes, and tolerance checks that print the error.
#include <Eigen/Geometry>
#include <cmath>
#include <memory>
#include <string>

#include "pg/core/image.h"
#include "pg/core/se3.h"
#include "pg/core/sensor.h"
#include "pg/sim/mesh.h"
#include "pg/sim/renderer.h"
#include "pg/tracker/contact_cloud.h"
#include "pg/tracker/point_cloud.h"

namespace pg::test {

// Front-end options that keep every contact pixel (no threshold relative to the deepest, never the
// core alone): the geometry tests measure the reconstruction itself, shallow contact edges
// included.
inline ContactCloudOptions all_contact_pixels() {
  ContactCloudOptions o;
  o.mask.relative_depth = 0.0;
  o.mask.core_relative_depth = 0.0;
  return o;
}

inline double deg(double rad) { return rad * 180.0 / kPi; }
inline double rad(double deg) { return deg * kPi / 180.0; }

// Camera depth t where pixel (x, y)'s ray meets the undeformed gel (bisection on
// t - distance - surface_z(d t) = 0; independent of the tracker's fixed-point version).
double gel_depth(const SensorModel& sensor, int x, int y);

// Unit normal of the undeformed gel surface z = surface_z(x, y) at the point seen by pixel (x, y)
// (+z, out of the gel).
Eigen::Vector3d gel_normal(const SensorModel& sensor, int x, int y);

// A sphere of radius R centred at c_sensor pressed into a rigid gel, computed analytically per
// pixel: where the sphere is nearer the camera than the gel, the gel takes the sphere's surface.
struct AnalyticFrame {
  ImageF normal;     // gel normals in S
  ImageF reference;  // the undeformed gel's normals (the no-contact frame)
  ImageF depth;      // indentation along the camera z axis [m]
};
AnalyticFrame analytic_sphere_frame(const SensorModel& sensor, const Eigen::Vector3d& c_sensor,
                                    double radius_m);

// Renders with a rigid gel and no noise (exact geometry): normals, depth, mask.
struct RenderCase {
  SensorModel sensor;
  std::shared_ptr<const ObjectShape> shape;
  std::unique_ptr<SensorRenderer> renderer;
};
RenderCase make_render_case(const std::string& preset, std::shared_ptr<const ObjectShape> shape);
RenderCase make_render_case(const SensorModel& sensor, std::shared_ptr<const ObjectShape> shape);
RenderedFrame render(const RenderCase& rc, const SE3& T_sensor_object);

std::shared_ptr<const ObjectShape> mesh_shape(const std::string& file_in_meshes);

// The pose that presses the mesh point `tip_object` (moving along `direction_object`, the
// object's outward direction at the tip) into the gel centre by press_m.
SE3 press_pose(const Eigen::Vector3d& tip_object, const Eigen::Vector3d& direction_object,
               double press_m, double roll_rad = 0.0);

// Distance of each point (object frame) to the mesh's surface, brute force over the triangles
// near the points.
std::vector<double> distances_to_mesh(const TriangleMesh& mesh,
                                      const std::vector<Eigen::Vector3f>& points_object);
double rms(const std::vector<double>& v);

}  // namespace pg::test
