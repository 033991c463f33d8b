// Random presses (pg::random_presses, the learned normals' training scenes and `tacsim
// presses`): every frame one press of the asked depth inside the asked area, the same for one
// seed; an object that cannot press inside it is an error naming the frame; the visible gel
// lies inside the image.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "pg/sim/presses.h"
#include "pg/sim/primitives.h"

namespace pg {
namespace {

SE3 press_pose(const Waypoint& w) { return SE3(quaternion_from_rpy(w.rpy_rad), w.position_m); }

// The press's depth and reach, written here rather than taken from measure_press, which placed
// the presses: every surface point's depth below the undeformed gel, the deepest, and the
// largest |x| and |y| of the points below it.
struct Measured {
  double depth_m = 0;
  Eigen::Vector2d max_abs_xy_m = Eigen::Vector2d::Zero();
};
Measured measure(const std::vector<Eigen::Vector3d>& points, const SE3& pose, const GelModel& gel) {
  Measured m;
  for (const Eigen::Vector3d& p : points) {
    const Eigen::Vector3d q = pose * p;
    const double below = gel.surface_z(q.x(), q.y()) - q.z();
    m.depth_m = std::max(m.depth_m, below);
    if (below > 0) {
      m.max_abs_xy_m.x() = std::max(m.max_abs_xy_m.x(), std::abs(q.x()));
      m.max_abs_xy_m.y() = std::max(m.max_abs_xy_m.y(), std::abs(q.y()));
    }
  }
  return m;
}

TEST(RandomPresses, EveryFrameIsOnePressOfTheAskedDepthInsideTheArea) {
  const GelModel gel = sensor_preset("digit").gel;
  const TriangleMesh box = make_box(Eigen::Vector3f(0.010f, 0.006f, 0.004f));
  const TriangleMesh sphere = make_uv_sphere(0.006f, 32, 64);
  for (const TriangleMesh* mesh : {&box, &sphere}) {
    const std::vector<Eigen::Vector3d> points = surface_grid(*mesh, 0.25e-3);
    EXPECT_EQ(surface_grid_size(*mesh, 0.25e-3), points.size());
    RandomPressOptions options;
    options.frames = 30;
    options.min_depth_m = 0.4e-3;
    options.max_depth_m = 1.2e-3;
    options.seed = 7;
    const std::vector<Waypoint> presses = random_presses(points, gel, options);
    ASSERT_EQ(presses.size(), 30u);
    // Measured on a grid five times finer than the one that placed them: a sphere's depth
    // differs by spacing^2 / 8 r (1.3 um), the contact's reach by up to the coarse spacing.
    const std::vector<Eigen::Vector3d> fine = surface_grid(*mesh, 0.05e-3);
    double shallowest = std::numeric_limits<double>::infinity(), deepest = 0;
    for (std::size_t k = 0; k < presses.size(); ++k) {
      EXPECT_EQ(presses[k].frame, int(k));
      const Measured c = measure(fine, press_pose(presses[k]), gel);
      EXPECT_GE(c.depth_m, options.min_depth_m - 5e-6) << "frame " << k;
      EXPECT_LE(c.depth_m, options.max_depth_m + 5e-6) << "frame " << k;
      EXPECT_LE(c.max_abs_xy_m.x(), options.contact_half_m.x() + 0.25e-3) << "frame " << k;
      EXPECT_LE(c.max_abs_xy_m.y(), options.contact_half_m.y() + 0.25e-3) << "frame " << k;
      shallowest = std::min(shallowest, c.depth_m);
      deepest = std::max(deepest, c.depth_m);
    }
    // The depths spread over the range, not all at one end.
    EXPECT_LT(shallowest, 0.6e-3);
    EXPECT_GT(deepest, 1.0e-3);
    // The same seed gives the same presses, another seed others.
    const std::vector<Waypoint> again = random_presses(points, gel, options);
    for (std::size_t k = 0; k < presses.size(); ++k) {
      EXPECT_EQ(again[k].position_m, presses[k].position_m);
      EXPECT_EQ(again[k].rpy_rad, presses[k].rpy_rad);
    }
    options.seed = 8;
    EXPECT_NE(random_presses(points, gel, options)[0].position_m, presses[0].position_m);
  }
}

TEST(RandomPresses, AnObjectThatCannotPressInsideTheAreaIsAnErrorNamingTheFrame) {
  // A 6 mm sphere pressed 1 mm deep touches a disc of about 3.5 mm radius: never inside 0.5 mm.
  const std::vector<Eigen::Vector3d> points = surface_grid(make_uv_sphere(0.006f, 16, 32), 0.25e-3);
  RandomPressOptions options;
  options.min_depth_m = 1e-3;
  options.contact_half_m = Eigen::Vector2d(0.5e-3, 0.5e-3);
  try {
    random_presses(points, sensor_preset("digit").gel, options);
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("frame 0: no press"), std::string::npos) << message;
    EXPECT_NE(message.find("too large"), std::string::npos) << message;
  }
  EXPECT_THROW(random_presses({}, sensor_preset("digit").gel, RandomPressOptions{}), InputError);
}

// The visible gel reaches the image's edge in one direction and stays inside it in the other,
// on every preset (centred) and with the principal point off the image's centre; a camera that
// sees none of its gel is an error.
TEST(RandomPresses, TheVisibleGelLiesInsideTheImage) {
  std::vector<SensorModel> sensors;
  for (const std::string& name : sensor_preset_names()) sensors.push_back(sensor_preset(name));
  SensorModel off_centre = sensor_preset("digit");
  off_centre.camera.cx = 20;  // of 120 px: the camera sees more of the gel's +x side
  sensors.push_back(off_centre);
  for (const SensorModel& sensor : sensors) {
    const std::string name = sensor.name + " cx " + std::to_string(sensor.camera.cx);
    const GelArea area = visible_gel_area(sensor);
    const Eigen::Vector2d lo = area.centre_m - area.half_m, hi = area.centre_m + area.half_m;
    EXPECT_GT(area.half_m.x(), 0.2 * sensor.gel.width_m) << name;
    EXPECT_GT(area.half_m.y(), 0.2 * sensor.gel.height_m) << name;
    EXPECT_GE(lo.x(), -0.5 * sensor.gel.width_m) << name;
    EXPECT_LE(hi.x(), 0.5 * sensor.gel.width_m) << name;
    const CameraModel& cam = sensor.camera;
    const auto pixel = [&](double x, double y) {
      const Eigen::Vector3d p_sensor(x, y, sensor.gel.surface_z(x, y));
      return cam.project(cam.T_sensor_camera().inverse() * p_sensor);
    };
    for (const double x : {lo.x(), hi.x()}) {
      for (const double y : {lo.y(), hi.y()}) {
        // The corners of the visible rectangle: inside the image.
        const Eigen::Vector2d uv = pixel(x, y);
        EXPECT_GE(uv.x(), -1e-3) << name;
        EXPECT_LE(uv.x(), cam.width - 1 + 1e-3) << name;
        EXPECT_GE(uv.y(), -1e-3) << name;
        EXPECT_LE(uv.y(), cam.height - 1 + 1e-3) << name;
      }
    }
    // A tenth of the width further along +x, at the corner row, is outside (the bound is tight).
    const Eigen::Vector2d beyond = pixel(hi.x() + 0.2 * area.half_m.x(), hi.y());
    EXPECT_TRUE(beyond.x() > cam.width - 1 || beyond.y() > cam.height - 1 ||
                hi.x() == 0.5 * sensor.gel.width_m)
        << name;
  }
  EXPECT_GT(visible_gel_area(off_centre).centre_m.x(), 1e-3);
  // Presses there stay inside the off-centre area.
  const std::vector<Eigen::Vector3d> points = surface_grid(make_uv_sphere(0.004f, 16, 32), 2.5e-4);
  const GelArea area = visible_gel_area(off_centre);
  RandomPressOptions options;
  options.frames = 10;
  options.centre_m = area.centre_m;
  options.target_half_m = 0.45 * area.half_m;
  options.contact_half_m = 0.85 * area.half_m;
  for (const Waypoint& w : random_presses(points, off_centre.gel, options)) {
    const PressContact c = measure_press(points, press_pose(w), off_centre.gel);
    EXPECT_GE(c.min_xy_m.x(), area.centre_m.x() - area.half_m.x()) << "frame " << w.frame;
    EXPECT_LE(c.max_xy_m.x(), area.centre_m.x() + area.half_m.x()) << "frame " << w.frame;
  }
  SensorModel blind = sensor_preset("digit");
  blind.camera.cx = 5000;
  EXPECT_THROW(visible_gel_area(blind), InputError);
}

}  // namespace
}  // namespace pg
