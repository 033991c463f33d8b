#include <gtest/gtest.h>

#include "pg/core/numbers.h"
#include "pg/core/trajectory.h"

namespace pg {
namespace {

TEST(Trajectory, WaypointsInterpolateLinearlyAndBySlerp) {
  const Trajectory t = Trajectory::from_waypoints(
      {{10, {0, 0, 0}, {0, 0, 0}}, {20, {0.01, 0, -0.002}, {0, 0, 0.4}}, {40, {0.01, 0.02, 0}, {0.2, 0, 0.4}}});
  // Held before the first and after the last waypoint.
  EXPECT_NEAR(t.at(0).translation().norm(), 0.0, 1e-15);
  EXPECT_NEAR((t.at(99).translation() - Eigen::Vector3d(0.01, 0.02, 0)).norm(), 0, 1e-15);
  // A quarter of the way from frame 10 to 20.
  const SE3 p = t.at(12);
  EXPECT_NEAR((p.translation() - Eigen::Vector3d(0.002, 0, -0.0004)).norm(), 0, 1e-12);
  EXPECT_NEAR(rotation_angle(p.rotation()), 0.08, 1e-12);
  // Exactly at a waypoint.
  EXPECT_NEAR(rotation_distance(t.at(20), pose_from_position_rpy({0.01, 0, -0.002}, {0, 0, 0.4})),
              0, 1e-12);
  // Equal angular steps along a segment (slerp, not linear quaternion blending).
  const double a1 = rotation_distance(t.at(20), t.at(21));
  const double a2 = rotation_distance(t.at(38), t.at(39));
  EXPECT_NEAR(a1, a2, 1e-9);
}

TEST(Trajectory, WaypointsFarApartInterpolateWithoutOverflow) {
  // The frame differences exceed an int's range.
  const Trajectory t = Trajectory::from_waypoints(
      {{-2147483647, {0, 0, 0.005}, {0, 0, 0}}, {2147483647, {0, 0, 0.006}, {0, 0, 0}}});
  EXPECT_NEAR(t.at(0).translation().z(), 0.0055, 1e-12);
  const Trajectory u = Trajectory::from_waypoints(
      {{-1500000000, {0, 0, 0.005}, {0, 0, 0}}, {1500000000, {0, 0, 0.006}, {0, 0, 0}}});
  EXPECT_NEAR(u.at(0).translation().z(), 0.0055, 1e-12);
}

// A yaw from 3.1 to -3.1 rad turns the short way through pi, and the quaternions frame by frame
// stay on one side (q and -q are one rotation): the waypoint at the end had come out negated, a
// jump of 2 in poses.csv for anyone filtering or differencing quaternions. The same for per-frame
// poses.
TEST(Trajectory, QuaternionsRunOnWithoutASignJump) {
  const Trajectory t = Trajectory::from_waypoints({{0, {0, 0, 0.005}, {0, 0, 3.1}},
                                                   {10, {0, 0, 0.005}, {0, 0, -3.1}},
                                                   {20, {0, 0, 0}, {3.1, 0, 0}}});
  std::vector<SE3> poses;
  for (int f = 0; f <= 20; ++f)
    poses.push_back(pose_from_position_rpy({0, 0, 0}, {0, 0, 3.0 + 0.02 * f}));
  const Trajectory p = Trajectory::from_poses(poses);
  for (const Trajectory* tr : {&t, &p}) {
    for (int f = 1; f <= 20; ++f) {
      EXPECT_GT(tr->at(f).rotation().dot(tr->at(f - 1).rotation()), 0.9) << "frame " << f;
    }
  }
  EXPECT_NEAR(rotation_distance(t.at(10), pose_from_position_rpy({0, 0, 0.005}, {0, 0, -3.1})), 0,
              1e-12);
  EXPECT_NEAR(rotation_distance(t.at(5), pose_from_position_rpy({0, 0, 0}, {0, 0, kPi})), 0, 1e-9);
}

TEST(Trajectory, PerFramePosesHoldTheLast) {
  std::vector<SE3> poses;
  for (int i = 0; i < 5; ++i) poses.push_back(SE3::Translation({0.001 * i, 0, 0}));
  const Trajectory t = Trajectory::from_poses(poses);
  EXPECT_DOUBLE_EQ(t.at(3).translation().x(), 0.003);
  EXPECT_DOUBLE_EQ(t.at(10).translation().x(), 0.004);
}

TEST(Trajectory, DefaultIsIdentityAndConstantIsConstant) {
  EXPECT_NEAR(Trajectory().at(7).log().norm(), 0.0, 1e-15);
  const SE3 pose = pose_from_position_rpy({1, 2, 3}, {0.1, 0.2, 0.3});
  EXPECT_NEAR(ominus(Trajectory::constant(pose).at(123), pose).norm(), 0.0, 1e-12);
}

}  // namespace
}  // namespace pg
