// Random presses (pg::random_presses, the learned normals' training scenes and `tacsim
// presses`): every frame one press of the asked depth inside the asked area, the same for one
// seed; an object that cannot press inside it is an error naming the frame; the visible gel
// lies inside the image.
#include <gtest/gtest.h>

#include <limits>
#include <string>

#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "pg/sim/presses.h"
#include "pg/sim/primitives.h"

namespace pg {
namespace {

SE3 press_pose(const Waypoint& w) { return SE3(quaternion_from_rpy(w.rpy_rad), w.position_m); }

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
      const PressContact c = measure_press(fine, press_pose(presses[k]), gel);
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

// The visible gel's half extents reach the image's edge in one direction and stay inside it in
// the other, on every preset.
TEST(RandomPresses, TheVisibleGelLiesInsideTheImage) {
  for (const std::string& name : sensor_preset_names()) {
    const SensorModel sensor = sensor_preset(name);
    const Eigen::Vector2d half = visible_gel_half_m(sensor);
    EXPECT_GT(half.x(), 0.25 * sensor.gel.width_m) << name;
    EXPECT_GT(half.y(), 0.25 * sensor.gel.height_m) << name;
    EXPECT_LE(half.x(), 0.5 * sensor.gel.width_m) << name;
    EXPECT_LE(half.y(), 0.5 * sensor.gel.height_m) << name;
    const CameraModel& cam = sensor.camera;
    const auto pixel = [&](double x, double y) {
      const Eigen::Vector3d p_sensor(x, y, sensor.gel.surface_z(x, y));
      return cam.project(cam.T_sensor_camera().inverse() * p_sensor);
    };
    for (const double sx : {-1.0, 1.0}) {
      for (const double sy : {-1.0, 1.0}) {
        // The corner of the visible rectangle: inside the image.
        const Eigen::Vector2d uv = pixel(sx * half.x(), sy * half.y());
        EXPECT_GE(uv.x(), -1e-3) << name;
        EXPECT_LE(uv.x(), cam.width - 1 + 1e-3) << name;
        EXPECT_GE(uv.y(), -1e-3) << name;
        EXPECT_LE(uv.y(), cam.height - 1 + 1e-3) << name;
      }
    }
    // A tenth further along x, at the image's corner row, is outside (the bound is tight).
    const Eigen::Vector2d beyond = pixel(1.1 * half.x(), half.y());
    EXPECT_TRUE(beyond.x() > cam.width - 1 || beyond.y() > cam.height - 1 ||
                half.x() == 0.5 * sensor.gel.width_m)
        << name;
  }
}

}  // namespace
}  // namespace pg
