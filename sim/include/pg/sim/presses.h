#pragma once
// Pressing a mesh into a sensor's gel, measured on points of its surface: how deep and how far
// out a pose presses, and independent random presses, the training data of a learned-normals
// model (scenes/normals/, written by make_scenes; `tacsim presses` for any mesh and sensor).
#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <limits>
#include <vector>

#include "pg/core/se3.h"
#include "pg/core/sensor.h"
#include "pg/core/trajectory.h"
#include "pg/sim/mesh.h"

namespace pg {

// Points on the mesh's surface at most spacing_m apart: a grid on each triangle, its corners
// and edges included. The vertices alone are too coarse: on the convex gel the middle of a long
// straight edge reaches deeper than its ends.
std::vector<Eigen::Vector3d> surface_grid(const TriangleMesh& mesh, double spacing_m);
// How many points surface_grid(mesh, spacing_m) makes, without making them: a triangle of longest
// edge L makes about (L / spacing)^2 / 2, however thin it is.
std::size_t surface_grid_size(const TriangleMesh& mesh, double spacing_m);

struct PressContact {
  // The deepest point below the undeformed gel surface [m]; negative when nothing touches.
  double depth_m = -std::numeric_limits<double>::infinity();
  Eigen::Vector2d max_abs_xy_m = Eigen::Vector2d::Zero();  // largest |x|, |y| in S that penetrates
  // The penetrating points' bounds in S [m] (+inf / -inf when none penetrates).
  Eigen::Vector2d min_xy_m = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d max_xy_m = Eigen::Vector2d::Constant(-std::numeric_limits<double>::infinity());
};

// How points of an object (in its frame) at T_sensor_object press into the gel.
PressContact measure_press(const std::vector<Eigen::Vector3d>& p_object, const SE3& T_sensor_object,
                           const GelModel& gel);

// The mean of the points within 0.1 mm of the farthest along `direction`, among those whose z
// lies in [z_lo, z_hi]: the corner, edge, face or stud tops an orientation presses first.
// Throws std::runtime_error when no point lies in the band.
Eigen::Vector3d extreme_centroid(const std::vector<Eigen::Vector3d>& points,
                                 const Eigen::Vector3d& direction, double z_lo, double z_hi);

struct RandomPressOptions {
  int frames = 50;
  double min_depth_m = 0.3e-3, max_depth_m = 1.5e-3;  // each press's depth, uniform [m]
  // The middle of the area the presses go to, in S [m] (off the gel's centre when the camera's
  // principal point is).
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  // Where the point pressing first lands: x and y within +-this of centre_m, uniform [m].
  Eigen::Vector2d target_half_m{4e-3, 5e-3};
  // Every penetrating point stays within +-this of centre_m [m]: inside what the camera sees.
  Eigen::Vector2d contact_half_m{7.2e-3, 9e-3};
  std::uint64_t seed = 1;
  int attempts = 100;  // draws per frame before giving up
};

// One press per frame: a uniformly random orientation (Shoemake's method), the point that
// touches first at a random place, pushed to a random depth; a draw whose contact leaves
// contact_half_m is drawn again. Returned as T_sensor_object waypoints, one per frame, rounded
// as a scene file shows them (positions to 0.1 um, roll, pitch and yaw to 1 urad) and measured
// after rounding. Deterministic for the points, gel and options. Throws InputError when a frame
// finds no such press in `attempts` draws (an object too large for the visible gel).
// `on_frame`, if given, is called with the number of presses found after each (a progress line;
// it may throw to stop).
std::vector<Waypoint> random_presses(const std::vector<Eigen::Vector3d>& p_object,
                                     const GelModel& gel, const RandomPressOptions& options,
                                     const std::function<void(int done)>& on_frame = {});

// Where a sensor's camera sees its gel: the rectangle of the undeformed gel (in S, within the
// gel's own size) that every row and column of the image reaches. Throws InputError when the
// camera sees none of the gel (a principal point far off the image).
struct GelArea {
  Eigen::Vector2d centre_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d half_m = Eigen::Vector2d::Zero();
};
// Throws InputError for a sensor a sensor file could not give (check_sensor_model).
GelArea visible_gel_area(const SensorModel& sensor);

}  // namespace pg
