// Point-to-plane ICP: Jacobians against numeric differentiation, the nearest-neighbour search
// (voxel grid and k-d tree) against brute force, recovery of known transforms between renders
// (clean and with outliers), degeneracy on a flat patch and a sphere, the information matrix's
// convention, and bad input.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "pg/sim/primitives.h"
#include "pg/tracker/contact_cloud.h"
#include "pg/tracker/icp.h"
#include "tracker_test_util.h"

namespace pg {
namespace {

using namespace pg::test;

SE3 random_pose(std::mt19937& rng, double t_m, double r_rad) {
  std::normal_distribution<double> g(0, 1);
  Vector6d xi;
  xi << Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized() * t_m,
      Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized() * r_rad;
  return SE3::exp(xi);
}

TEST(PointToPlane, JacobiansMatchNumericDifferentiation) {
  std::mt19937 rng(11);
  std::normal_distribution<double> g(0, 1);
  const double h = 1e-6;
  for (int trial = 0; trial < 20; ++trial) {
    const SE3 T = random_pose(rng, 0.01, 0.5);
    const Eigen::Vector3d p(g(rng) * 0.01, g(rng) * 0.01, g(rng) * 0.01);
    const Eigen::Vector3d q(g(rng) * 0.01, g(rng) * 0.01, g(rng) * 0.01);
    const Eigen::Vector3d n = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    const Matrix16d J_left = point_to_plane_jacobian_left(T, p, n);
    const Matrix16d J_right = point_to_plane_jacobian_right(T, p, n);
    for (int k = 0; k < 6; ++k) {
      const Vector6d e = Vector6d::Unit(k) * h;
      const double left = (point_to_plane_residual(SE3::exp(e) * T, p, q, n) -
                           point_to_plane_residual(SE3::exp(-e) * T, p, q, n)) /
                          (2 * h);
      const double right = (point_to_plane_residual(T * SE3::exp(e), p, q, n) -
                            point_to_plane_residual(T * SE3::exp(-e), p, q, n)) /
                           (2 * h);
      EXPECT_NEAR(J_left[k], left, 1e-7) << "trial " << trial << " column " << k;
      EXPECT_NEAR(J_right[k], right, 1e-7) << "trial " << trial << " column " << k;
    }
  }
}

TEST(PointToPlane, RobustWeightsDownweightLargeResiduals) {
  const double c = 1e-4;
  for (RobustKernel k : {RobustKernel::kNone, RobustKernel::kHuber, RobustKernel::kTukey}) {
    EXPECT_NEAR(robust_weight(k, c, 0.0), 1.0, 1e-12);
    EXPECT_NEAR(robust_weight(k, c, 0.3 * c), robust_weight(k, c, -0.3 * c), 1e-12);
  }
  EXPECT_NEAR(robust_weight(RobustKernel::kHuber, c, 4 * c), 0.25, 1e-12);
  EXPECT_EQ(robust_weight(RobustKernel::kTukey, c, 1.01 * c), 0.0);
  EXPECT_GT(robust_weight(RobustKernel::kTukey, c, 0.5 * c), 0.5);
}

TEST(KdTree, NearestAndTwoNearestMatchBruteForce) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-0.01f, 0.01f);
  PointCloud cloud;
  for (int i = 0; i < 3000; ++i) cloud.push_back({u(rng), u(rng), u(rng)}, {0, 0, 1});
  const PointCloudTree tree(cloud);
  for (int k = 0; k < 300; ++k) {
    const Eigen::Vector3f q(u(rng), u(rng), u(rng));
    std::vector<std::pair<float, int>> all;
    for (int i = 0; i < 3000; ++i) all.push_back({(cloud.points[i] - q).squaredNorm(), i});
    std::sort(all.begin(), all.end());
    float d_sq = 0;
    const float r = 0.0015f;
    const int j = tree.nearest(q, r, &d_sq);
    if (all[0].first < r * r) {
      EXPECT_EQ(j, all[0].second);
      EXPECT_FLOAT_EQ(d_sq, all[0].first);
    } else {
      EXPECT_EQ(j, -1);
    }
    const auto two = tree.nearest_two(q, r);
    for (int s = 0; s < 2; ++s) {
      if (all[s].first < r * r) {
        EXPECT_EQ(two.index[s], all[s].second);
        EXPECT_FLOAT_EQ(two.distance_sq[s], all[s].first);
      } else {
        EXPECT_EQ(two.index[s], -1);
        EXPECT_FLOAT_EQ(two.distance_sq[s], r * r);
      }
    }
  }
  // Nothing lies within a negative or NaN distance (a negative one, squared, had searched as far
  // as its size).
  for (const float bad : {-0.01f, std::nanf("")}) {
    EXPECT_EQ(tree.nearest(cloud.points[0], bad), -1) << bad;
    const auto none = tree.nearest_two(cloud.points[0], bad);
    EXPECT_EQ(none.index[0], -1) << bad;
    EXPECT_EQ(none.index[1], -1) << bad;
  }
}

// A point that is not finite is left out (it had put NaN points in the output and merged
// others); a cloud wider than the keys can count is refused (they had wrapped, merging points
// 21 m apart at 10 um voxels).
TEST(VoxelDownsample, NonFinitePointsAreLeftOutAndAnOverwideCloudRefused) {
  PointCloud in;
  for (int i = 0; i < 10; ++i) {
    in.push_back(Eigen::Vector3f(float(i) * 1e-3f, 0, 0), Eigen::Vector3f::UnitZ());
  }
  PointCloud with_nan = in;
  with_nan.push_back(Eigen::Vector3f(NAN, 0, 0), Eigen::Vector3f::UnitZ());
  with_nan.push_back(Eigen::Vector3f(INFINITY, 0, 0), Eigen::Vector3f::UnitZ());
  PointCloud a, b;
  voxel_downsample(in, 1e-4, a);
  voxel_downsample(with_nan, 1e-4, b);
  ASSERT_EQ(a.size(), 10u);
  ASSERT_EQ(b.size(), a.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a.points[i], b.points[i]);
  PointCloud wide;
  wide.push_back(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitZ());
  wide.push_back(Eigen::Vector3f(21.0f, 0, 0), Eigen::Vector3f::UnitZ());
  EXPECT_THROW(voxel_downsample(wide, 1e-5, a), std::invalid_argument);
  voxel_downsample(wide, 1e-3, a);
  EXPECT_EQ(a.size(), 2u);
}

TEST(VoxelDownsample, OnePointPerVoxelAtTheCentroidWithUnitNormals) {
  std::mt19937 rng(8);
  std::uniform_real_distribution<float> u(0.0f, 0.004f);
  PointCloud cloud;
  for (int i = 0; i < 5000; ++i) {
    cloud.push_back({u(rng), u(rng), 0.001f}, Eigen::Vector3f(u(rng), u(rng), 0.01f).normalized());
  }
  PointCloud out;
  voxel_downsample(cloud, 0.001, out);
  EXPECT_EQ(out.size(), 16u);  // 4 x 4 voxels on the plane
  for (std::size_t i = 0; i < out.size(); ++i) {
    EXPECT_NEAR(out.points[i].z(), 0.001f, 1e-7);
    EXPECT_NEAR(out.normals[i].norm(), 1.0f, 1e-5);
    // Centroid of ~300 uniform points: near the voxel centre.
    const Eigen::Vector3f centre = ((out.points[i] / 0.001f).array().floor() + 0.5f) * 0.001f;
    EXPECT_LT((out.points[i] - centre).head<2>().norm(), 0.0001f);
  }
}

// ---------------------------------------------------------------------------------------------
// Registration of two renders of the same object, `delta` apart.

struct TwoRenders {
  PointCloud cloud_a, cloud_b;  // each in its own sensor frame
  SE3 T_a_b;                    // truth: maps frame B's sensor coordinates to frame A's
};

TwoRenders two_renders(const RenderCase& rc, const SE3& T_sensor_object_a, const SE3& delta) {
  const SE3 T_sensor_object_b = delta * T_sensor_object_a;
  ContactCloudBuilder builder(rc.sensor, test::all_contact_pixels(),
                              rc.renderer->undeformed_normals());
  TwoRenders out;
  out.cloud_a = builder.build(render(rc, T_sensor_object_a).images.normal).cloud_sensor;
  out.cloud_b = builder.build(render(rc, T_sensor_object_b).images.normal).cloud_sensor;
  // p_a = T_sa_o o and p_b = T_sb_o o, so p_a = T_sa_o T_sb_o^-1 p_b.
  out.T_a_b = T_sensor_object_a * T_sensor_object_b.inverse();
  return out;
}

// 0.5 mm and 3 degrees: a translation mostly along the gel and a rotation about an oblique axis
// through the contact.
SE3 test_motion() {
  const Eigen::Vector3d axis = Eigen::Vector3d(0.3, 1.0, 0.4).normalized();
  const Eigen::Quaterniond q(Eigen::AngleAxisd(rad(3.0), axis));
  const Eigen::Vector3d pivot(0, 0, -0.001);
  const Eigen::Vector3d t = Eigen::Vector3d(0.4, -0.28, 0.08).normalized() * 0.0005;
  return SE3::Translation(t) * SE3::Translation(pivot) * SE3(q, Eigen::Vector3d::Zero()) *
         SE3::Translation(-pivot);
}

void add_outliers(PointCloud& cloud, double fraction, std::mt19937& rng) {
  // Points scattered over the cloud's extent and 0.2-1 mm off it.
  Eigen::Vector3f lo = cloud.points[0], hi = lo;
  for (const auto& p : cloud.points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  std::uniform_real_distribution<float> u(0, 1);
  const int n = int(std::lround(fraction / (1 - fraction) * cloud.size()));
  const std::size_t original = cloud.size();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3f& base = cloud.points[std::size_t(u(rng) * (original - 1))];
    const Eigen::Vector3f dir =
        Eigen::Vector3f(u(rng) - 0.5f, u(rng) - 0.5f, u(rng) - 0.5f).normalized();
    cloud.push_back(base + dir * (0.0002f + 0.0008f * u(rng)), dir);
  }
}

struct Error {
  double translation_m, rotation_rad;
};
Error pose_error(const SE3& estimate, const SE3& truth) {
  return {translation_distance(estimate, truth), rotation_distance(estimate, truth)};
}

void check_registration(const std::string& name, const RenderCase& rc, const SE3& pose,
                        double outlier_fraction, RobustKernel kernel, double max_translation_m,
                        double max_rotation_rad, bool must_converge = true) {
  TwoRenders tr = two_renders(rc, pose, test_motion());
  ASSERT_GT(tr.cloud_a.size(), 200u) << name;
  ASSERT_GT(tr.cloud_b.size(), 200u) << name;
  std::mt19937 rng(21);
  if (outlier_fraction > 0) add_outliers(tr.cloud_b, outlier_fraction, rng);
  const PointCloudTree target(tr.cloud_a);
  IcpOptions options;
  options.kernel = kernel;
  PointToPlaneIcp icp(options);
  const IcpResult r = icp.align(tr.cloud_b, target, SE3::Identity());
  const Error e = pose_error(r.T_target_source, tr.T_a_b);
  const Error start = pose_error(SE3::Identity(), tr.T_a_b);
  std::printf(
      "  %-34s %5zu/%5zu pts, %2d it, %s, inliers %d, rms %.4f mm: error %.4f mm %.4f deg "
      "(from %.3f mm %.2f deg), %d unconstrained, %ld queries\n",
      name.c_str(), tr.cloud_b.size(), tr.cloud_a.size(), r.iterations, to_string(r.status),
      r.inliers, r.rms_m * 1e3, e.translation_m * 1e3, deg(e.rotation_rad),
      start.translation_m * 1e3, deg(start.rotation_rad), r.degeneracy.unconstrained,
      icp.last_queries());
  if (must_converge) {
    EXPECT_TRUE(r.converged) << name << ": " << to_string(r.status);
  }
  EXPECT_EQ(r.degeneracy.unconstrained, 0) << name;
  EXPECT_LT(e.translation_m, max_translation_m) << name << ": " << e.translation_m * 1e3 << " mm";
  EXPECT_LT(e.rotation_rad, max_rotation_rad) << name << ": " << deg(e.rotation_rad) << " deg";
}

SE3 cube_corner_pose() {
  const double tip = 0.009 + 0.001 / std::sqrt(3.0);
  return press_pose({tip, tip, tip}, {1, 1, 1}, 0.0015, 0.3);
}
SE3 brick_pose() { return press_pose({0.0159, 0.0079, 0.00395}, {1, 1, 2}, 0.0012, 0.2); }

// At the real DIGIT stream's 240x320 the targets hold: 0.02 mm and 0.05 deg. At the
// paper's 120x160 the translation target holds but the rotation error is 0.02-0.18 deg (the toy
// brick's 0.18; 0.14 with every pair used whatever its normals, 0.14-0.22 with the target's
// normals alone): the patches are small (250-400 points over 2-3 mm) and nearest-neighbour pairs
// on a 0.16 mm pixel grid across the brick's 0.2 mm stud rim limit it, so 120x160 is held to 0.3
// deg.
TEST(IcpRenders, RecoversTheMotionBetweenTwoRendersOfTheCubeCornerAndTheToyBrick) {
  for (const char* preset : {"digit_240x320", "digit"}) {
    const bool full = std::string(preset) == "digit_240x320";
    const double max_rotation = rad(full ? 0.05 : 0.3);
    const RenderCase cube = make_render_case(preset, mesh_shape("cube.glb"));
    const RenderCase brick = make_render_case(preset, mesh_shape("toy_brick.glb"));
    check_registration(std::string("cube corner ") + preset, cube, cube_corner_pose(), 0.0,
                       RobustKernel::kHuber, 0.02e-3, max_rotation);
    check_registration(std::string("toy brick ") + preset, brick, brick_pose(), 0.0,
                       RobustKernel::kHuber, 0.02e-3, max_rotation);
  }
}

// 10% of the source points 0.2-1 mm off the surface. Tukey's biweight rejects them (and
// converges, except on the toy brick's 260 points at 120x160, where one pair switches in and out
// of the kernel and the last steps cycle between two poses 0.4 mrad apart: the answer is as good,
// and the tracker does not use a registration that hit the iteration limit); Huber only bounds
// their pull (0.01 mm, 0.5 deg) and converges slowly.
TEST(IcpRenders, RobustKernelKeepsTheErrorSmallWithTenPercentOutliers) {
  for (const char* preset : {"digit_240x320", "digit"}) {
    const bool full = std::string(preset) == "digit_240x320";
    const RenderCase cube = make_render_case(preset, mesh_shape("cube.glb"));
    const RenderCase brick = make_render_case(preset, mesh_shape("toy_brick.glb"));
    check_registration(std::string("cube corner + 10% outliers ") + preset + " tukey", cube,
                       cube_corner_pose(), 0.1, RobustKernel::kTukey, 0.05e-3,
                       rad(full ? 0.1 : 0.3));
    check_registration(std::string("toy brick + 10% outliers ") + preset + " tukey", brick,
                       brick_pose(), 0.1, RobustKernel::kTukey, 0.05e-3, rad(full ? 0.1 : 0.3),
                       full);
    check_registration(std::string("cube corner + 10% outliers ") + preset + " huber", cube,
                       cube_corner_pose(), 0.1, RobustKernel::kHuber, 0.05e-3, rad(1.0), false);
  }
}

// ---------------------------------------------------------------------------------------------
// Degeneracy: synthetic patches whose unobservable directions are known.

// A 4 x 4 mm grid on the plane z = 0 around (1, -2) mm, normals +z.
PointCloud flat_patch(double spacing_m) {
  PointCloud cloud;
  for (double x = -0.002; x <= 0.002 + 1e-12; x += spacing_m) {
    for (double y = -0.002; y <= 0.002 + 1e-12; y += spacing_m) {
      cloud.push_back(Eigen::Vector3f(float(0.001 + x), float(-0.002 + y), 0.0f), {0, 0, 1});
    }
  }
  return cloud;
}

// The cap of a sphere (radius R, centre s) within `cap_m` of its lowest point, outward normals.
PointCloud sphere_cap(const Eigen::Vector3d& s, double R, double cap_m, double spacing_m) {
  PointCloud cloud;
  for (double x = -cap_m; x <= cap_m + 1e-12; x += spacing_m) {
    for (double y = -cap_m; y <= cap_m + 1e-12; y += spacing_m) {
      if (x * x + y * y > cap_m * cap_m) continue;
      const Eigen::Vector3d n(x / R, y / R, -std::sqrt(1 - (x * x + y * y) / (R * R)));
      cloud.push_back((s + R * n).cast<float>(), n.cast<float>());
    }
  }
  return cloud;
}

// Distance of twist v from the column span of B (least squares), relative to |v|.
// The exact-search property of PointCloudTree on the surface clouds ICP meets (the grid's case):
// with the voxel grid (default) and with the k-d tree alone, nearest() and nearest_two() equal
// brute force for queries on, near, far from (k-d tree fallback) and outside the surface, with
// and without hints. A flat patch has a zero-height bounding box.
TEST(KdTree, VoxelGridAndKdTreeMatchBruteForceOnSurfaces) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  PointCloud cap = sphere_cap({0, 0, 0.006}, 0.006, 0.003, 0.00005);
  for (auto& p : cap.points) p += 1e-5f * Eigen::Vector3f(u(rng), u(rng), u(rng));  // jitter
  for (const PointCloud& cloud : {cap, flat_patch(0.0001)}) {
    const PointCloudTree with_grid(cloud), kd_only(cloud, 12, false);
    std::uniform_int_distribution<int> pick(0, int(cloud.size()) - 1);
    for (int k = 0; k < 2000; ++k) {
      // A surface point pushed along its normal by up to 2.5 mm (beyond the grid's rings), and
      // sometimes moved sideways off the patch.
      const int i = pick(rng);
      const float off = 0.0025f * u(rng) * u(rng) * u(rng);
      Eigen::Vector3f q = cloud.points[i] + off * cloud.normals[i];
      if (k % 10 == 0) q.x() += 0.004f * u(rng);
      std::vector<std::pair<float, int>> all;
      for (std::size_t j = 0; j < cloud.size(); ++j) {
        all.push_back({(cloud.points[j] - q).squaredNorm(), int(j)});
      }
      std::partial_sort(all.begin(), all.begin() + 2, all.end());
      const float r = 0.0015f;
      const int hint = k % 3 == 0 ? pick(rng) : -1;
      for (const PointCloudTree* tree : {&with_grid, &kd_only}) {
        const auto two = tree->nearest_two(q, r, hint);
        // Distances must match; indices too, up to ties (the flat patch is a regular grid).
        const auto index_distance_sq = [&](int j) { return (cloud.points[j] - q).squaredNorm(); };
        for (int s = 0; s < 2; ++s) {
          if (all[s].first < r * r) {
            ASSERT_GE(two.index[s], 0) << "query " << k << " slot " << s;
            ASSERT_FLOAT_EQ(index_distance_sq(two.index[s]), all[s].first) << "query " << k;
            EXPECT_FLOAT_EQ(two.distance_sq[s], all[s].first);
          } else {
            EXPECT_EQ(two.index[s], -1) << "query " << k << " slot " << s;
            EXPECT_FLOAT_EQ(two.distance_sq[s], r * r);
          }
        }
        if (two.index[1] >= 0) {
          EXPECT_NE(two.index[0], two.index[1]);
        }
        const int j = tree->nearest(q, 0.001f);
        if (all[0].first < 1e-6f) {
          ASSERT_GE(j, 0);
          EXPECT_FLOAT_EQ(index_distance_sq(j), all[0].first);
        } else {
          EXPECT_EQ(j, -1);
        }
      }
    }
  }
}

double off_span(const Vector6d& v, const Eigen::Matrix<double, 6, 3>& B) {
  const Eigen::Vector3d a = B.colPivHouseholderQr().solve(v);
  return (B * a - v).norm() / v.norm();
}

TEST(IcpDegeneracy, FlatPatchLeavesInPlaneTranslationAndYawAtTheGuess) {
  const PointCloud target = flat_patch(0.0001);
  const PointCloudTree tree(target);
  // The source is the target moved by the inverse of a motion with all six components.
  const SE3 truth =
      SE3::exp((Vector6d() << 0.0004, -0.0003, 0.0002, rad(1.5), rad(-1.0), rad(5.0)).finished());
  const PointCloud source = transform_cloud(truth.inverse(), target);
  PointToPlaneIcp icp;
  const IcpResult r = icp.align(source, tree, SE3::Identity());
  ASSERT_TRUE(r.converged) << to_string(r.status);
  EXPECT_EQ(r.degeneracy.unconstrained, 3);
  // The unconstrained twists (about the centre c) span x, y translation and rotation about z.
  Eigen::Matrix<double, 6, 3> B = Eigen::Matrix<double, 6, 3>::Zero();
  B(0, 0) = B(1, 1) = B(5, 2) = 1.0;
  const Matrix6Xd N = r.degeneracy.unconstrained_twists();
  for (int i = 0; i < N.cols(); ++i) EXPECT_LT(off_span(N.col(i), B), 1e-6) << N.col(i).transpose();
  std::printf("  flat patch eigenvalues (scaled): %s\n",
              ::testing::PrintToString(r.degeneracy.eigenvalues.transpose()).c_str());
  // The plane is aligned (z, roll, pitch recovered)...
  EXPECT_LT(r.rms_m, 1e-7);
  const Eigen::Matrix3d R = r.T_target_source.rotation_matrix();
  // (the source plane's normal R_truth^T e_z must map to e_z)
  EXPECT_LT((R.row(2) - truth.rotation_matrix().row(2)).norm(), 1e-6);
  // ... while x, y and yaw stay at the guess (identity) up to the second-order coupling of the
  // roll/pitch rotations (the truth has 0.4 mm, -0.3 mm and 5 deg there).
  const Eigen::Vector3d c = r.degeneracy.centre_target;
  const Eigen::Vector3d moved_c = r.T_target_source * (r.T_target_source.inverse() * c);
  (void)moved_c;
  const Eigen::Vector3d centroid_source = r.T_target_source.inverse() * c;
  const Eigen::Vector3d shift = r.T_target_source * centroid_source - centroid_source;
  EXPECT_LT(shift.head<2>().norm(), 0.01e-3) << "in-plane motion of the centroid [m]";
  const double yaw = std::atan2(R(1, 0) - R(0, 1), R(0, 0) + R(1, 1));
  EXPECT_LT(std::abs(yaw), rad(0.05)) << deg(yaw) << " deg";
}

TEST(IcpDegeneracy, SphereLeavesTheRotationsAboutItsCentreAtTheGuess) {
  const double R = 0.006;
  const Eigen::Vector3d s(0.0005, -0.001, 0.005);
  // The target cap is wide enough that the source cap, turned 10 deg about s (1 mm along the
  // surface), still lies inside it: no correspondences at the target's rim.
  const PointCloud target = sphere_cap(s, R, 0.004, 0.00005);
  const PointCloudTree tree(target);
  // Truth: a 10 deg rotation about the centre, then a translation.
  const Eigen::Quaterniond q(Eigen::AngleAxisd(rad(10), Eigen::Vector3d(1, 2, 0.5).normalized()));
  const SE3 truth = SE3::Translation({0.0003, -0.0002, 0.0001}) * SE3::Translation(s) *
                    SE3(q, Eigen::Vector3d::Zero()) * SE3::Translation(-s);
  const PointCloud source = transform_cloud(truth.inverse(), sphere_cap(s, R, 0.002, 0.00007));
  PointToPlaneIcp icp;
  const IcpResult r = icp.align(source, tree, SE3::Identity());
  ASSERT_TRUE(r.converged) << to_string(r.status);
  EXPECT_EQ(r.degeneracy.unconstrained, 3);
  std::printf("  sphere eigenvalues (scaled): %s\n",
              ::testing::PrintToString(r.degeneracy.eigenvalues.transpose()).c_str());
  // Rotations about s, as twists about c: [phi x (c - s); phi].
  const Eigen::Vector3d c = r.degeneracy.centre_target;
  Eigen::Matrix<double, 6, 3> B;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d phi = Eigen::Vector3d::Unit(k);
    B.col(k) << phi.cross(c - s), phi;
  }
  const Matrix6Xd N = r.degeneracy.unconstrained_twists();
  for (int i = 0; i < N.cols(); ++i) EXPECT_LT(off_span(N.col(i), B), 1e-2) << N.col(i).transpose();
  // The orientation stays at the guess; the centre is recovered.
  EXPECT_LT(rotation_angle(r.T_target_source.rotation()), rad(0.01));
  const Eigen::Vector3d s_source = truth.inverse() * s;
  EXPECT_LT((r.T_target_source * s_source - s).norm(), 1e-6);
}

TEST(IcpDegeneracy, RenderedSphereReportsThreeRotationsAndKeepsItsOrientation) {
  const double R = 0.006;
  const auto sphere = std::make_shared<ObjectShape>(make_uv_sphere(float(R), 90, 180));
  const RenderCase rc = make_render_case("digit_240x320", sphere);
  const SE3 pose_a = SE3::Translation({0.0005, -0.001, R - 0.001});
  // B: 0.3 mm along the gel and 8 deg about the sphere's centre.
  const Eigen::Quaterniond q(Eigen::AngleAxisd(rad(8), Eigen::Vector3d(0.2, 1, 0.3).normalized()));
  const SE3 pose_b =
      SE3::Translation({0.0003, 0.0001, 0}) * pose_a * SE3(q, Eigen::Vector3d::Zero());
  const TwoRenders tr = two_renders(rc, pose_a, pose_b * pose_a.inverse());
  const PointCloudTree tree(tr.cloud_a);
  const IcpResult r = PointToPlaneIcp().align(tr.cloud_b, tree, SE3::Identity());
  ASSERT_TRUE(r.converged) << to_string(r.status);
  std::printf("  rendered sphere eigenvalues (scaled): %s\n",
              ::testing::PrintToString(r.degeneracy.eigenvalues.transpose()).c_str());
  EXPECT_EQ(r.degeneracy.unconstrained, 3);
  EXPECT_LT(rotation_angle(r.T_target_source.rotation()), rad(0.05));
  // The centre of B's sphere lands on A's.
  const Eigen::Vector3d centre_a = pose_a.translation(), centre_b = pose_b.translation();
  EXPECT_LT((r.T_target_source * centre_b - centre_a).norm(), 0.005e-3);
}

// The cube's rounded edge (1 mm radius) pressed 0.8 mm, then turned 0.04 rad about the rounding's
// axis: the rounding itself cannot show the turn, the strips of the two flat faces beside it can
// (about 0.5 mm of each). Scaled by the cloud's RMS radius (the strip's length) that turn looked
// free (eigenvalue ratio about 2e-3) and stayed at the guess: the benchmark's edge sequences
// ended 0.1-0.25 rad off. Scaled by the extent about each axis it is constrained, and the slide
// along the edge, truly free, must still stay at the guess.
TEST(IcpDegeneracy, RoundedEdgeTurnIsMeasuredAndItsSlideStaysAtTheGuess) {
  const RenderCase cube = make_render_case("digit", mesh_shape("cube.glb"));
  const double h = 0.009;  // the rounding's axis: x = y = 9 mm, along z
  const Eigen::Vector3d tip(h + 0.001 / std::sqrt(2.0), h + 0.001 / std::sqrt(2.0), 0.002);
  const SE3 pose_a = press_pose(tip, {1, 1, 0}, 0.0008, 0.3);
  const Eigen::Vector3d axis_point(h, h, 0);
  const SE3 turn = SE3::Translation(axis_point) *
                   SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.04, Eigen::Vector3d::UnitZ())),
                       Eigen::Vector3d::Zero()) *
                   SE3::Translation(-axis_point);
  const SE3 pose_b = pose_a * turn;
  const TwoRenders tr = two_renders(cube, pose_a, pose_b * pose_a.inverse());
  ASSERT_GT(tr.cloud_b.size(), 300u);
  const PointCloudTree tree(tr.cloud_a);
  const IcpResult r = PointToPlaneIcp().align(tr.cloud_b, tree, SE3::Identity());
  const Error e = pose_error(r.T_target_source, tr.T_a_b);
  // The edge's direction in the sensor frame, and the estimate's motion of a point on it.
  const Eigen::Vector3d edge = pose_a.rotation() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d on_edge = pose_a * axis_point;
  const double slide = edge.dot(r.T_target_source * on_edge - tr.T_a_b * on_edge);
  std::printf(
      "  rounded edge: %zu points, %s, %d unconstrained, eigenvalues %s; turn 40 mrad, "
      "error %.2f mrad, %.4f mm, slide %.4f mm\n",
      tr.cloud_b.size(), to_string(r.status), r.degeneracy.unconstrained,
      ::testing::PrintToString(r.degeneracy.eigenvalues.transpose()).c_str(), e.rotation_rad * 1e3,
      e.translation_m * 1e3, slide * 1e3);
  EXPECT_TRUE(r.converged) << to_string(r.status);
  EXPECT_EQ(r.degeneracy.unconstrained, 1) << "the slide along the edge only";
  EXPECT_LT(e.rotation_rad, 0.008) << "at most a fifth of the turn left";
  EXPECT_LT(std::abs(slide), 0.02e-3);
}

TEST(IcpInformation, HessianIsInTheSourceFrameTangentAndMatchesTheJacobians) {
  // A cube-corner-like patch of three planes: well constrained. The planes' shared edges are
  // held by one plane each: coincident points of different normals would make each nearest
  // neighbour below a tie that float rounding breaks, differently in differently optimised builds.
  PointCloud target;
  for (int a = 0; a < 30; ++a) {
    for (int b = 0; b < 30; ++b) {
      const float u = 0.0001f * a, v = 0.0001f * b;
      target.push_back({u, v, 0}, {0, 0, -1});
      if (b > 0) target.push_back({u, 0, v}, {0, -1, 0});
      if (a > 0 && b > 0) target.push_back({0, u, v}, {-1, 0, 0});
    }
  }
  const PointCloudTree tree(target);
  const SE3 truth =
      SE3::exp((Vector6d() << 0.0001, 0.0002, -0.0001, 0.01, -0.02, 0.015).finished());
  const PointCloud source = transform_cloud(truth.inverse(), target);
  IcpOptions options;
  options.kernel = RobustKernel::kNone;
  // Target normals alone, as the sum below uses (the next test checks the symmetric objective).
  options.symmetric = false;
  const IcpResult r = PointToPlaneIcp(options).align(source, tree, SE3::Identity());
  ASSERT_TRUE(r.converged);
  EXPECT_EQ(r.degeneracy.unconstrained, 0);
  EXPECT_LT(translation_distance(r.T_target_source, truth), 1e-8);
  // Sum of J_right^T J_right over the correspondences at the optimum.
  Matrix6d H = Matrix6d::Zero();
  for (std::size_t i = 0; i < source.size(); ++i) {
    const Eigen::Vector3f p = (r.T_target_source * source.points[i].cast<double>()).cast<float>();
    const int j = tree.nearest(p, 1e-3f);
    ASSERT_GE(j, 0);
    const Matrix16d J = point_to_plane_jacobian_right(
        r.T_target_source, source.points[i].cast<double>(), target.normals[j].cast<double>());
    H += J.transpose() * J;
  }
  EXPECT_LT((r.hessian - H).norm(), 1e-6 * H.norm()) << r.hessian << "\n\n" << H;
  // Exact data: the residual sigma sits at its floor.
  EXPECT_DOUBLE_EQ(r.residual_sigma_m, options.min_residual_sigma_m);
  EXPECT_LT((r.information - H / (1e-5 * 1e-5)).norm(), 1e-6 * r.information.norm());
}

TEST(IcpInformation, RobustWeightsAndDistantPairsMatchADirectSum) {
  // Three planes as above, their grids shifted by half a spacing so that no two points coincide
  // (a tie would leave the normal of a pair to chance); every 7th source point pushed 0.4 mm off
  // its plane (Huber's linear zone: weight 1/4) and every 11th 2 mm (beyond the correspondence
  // distance: no pair).
  PointCloud target;
  for (int a = 0; a < 30; ++a) {
    for (int b = 0; b < 30; ++b) {
      const float u = 0.0001f * a, v = 0.0001f * b, h = 0.00005f;
      target.push_back({u, v, 0}, {0, 0, -1});
      target.push_back({u + h, 0, v + h}, {0, -1, 0});
      target.push_back({0, u + h, v + h}, {-1, 0, 0});
    }
  }
  const PointCloudTree tree(target);
  const SE3 truth = SE3::exp((Vector6d() << 0.0001, -0.0002, 0.0001, -0.01, 0.02, 0.01).finished());
  PointCloud source = transform_cloud(truth.inverse(), target);
  for (std::size_t i = 0; i < source.size(); ++i) {
    if (i % 11 == 0) {
      source.points[i] += 2e-3f * source.normals[i];
    } else if (i % 7 == 0) {
      source.points[i] += 4e-4f * source.normals[i];
    }
  }
  // The source normals of every 5th point turned by 0.2 rad (each pair's plane normal then
  // differs from the target's under the symmetric objective) and of every 13th reversed (that
  // pair falls back to the target's normal, or is left out, with either objective, with the
  // pairs' normals limited to 0.25 rad apart, the default).
  for (std::size_t i = 0; i < source.size(); ++i) {
    if (i % 13 == 0) {
      source.normals[i] = -source.normals[i];
    } else if (i % 5 == 0) {
      const Eigen::Vector3f axis = source.normals[i].unitOrthogonal();
      source.normals[i] = Eigen::AngleAxisf(0.2f, axis) * source.normals[i];
    }
  }
  struct Case {
    bool symmetric;
    double max_normal_angle_rad;
    const char* name;
  };
  const double limit = IcpOptions().max_normal_angle_rad;
  for (const Case& c :
       {Case{true, limit, "symmetric, limited"}, Case{true, 0.0, "symmetric"},
        Case{false, limit, "target normals, limited"}, Case{false, 0.0, "target normals"}}) {
    SCOPED_TRACE(c.name);
    IcpOptions options;  // Huber, scale 0.1 mm, pairs within 1 mm
    ASSERT_EQ(options.kernel, RobustKernel::kHuber);
    ASSERT_EQ(IcpOptions().max_normal_angle_rad, 0.25);
    options.symmetric = c.symmetric;
    options.max_normal_angle_rad = c.max_normal_angle_rad;
    const IcpResult r = PointToPlaneIcp(options).align(source, tree, SE3::Identity());
    ASSERT_TRUE(r.converged) << to_string(r.status);
    // Sum of w J_right^T J_right over the pairs within the correspondence distance (and, when
    // limited, whose normals are within the limit).
    Matrix6d H = Matrix6d::Zero();
    int pairs = 0, down_weighted = 0, own_normal = 0, left_out = 0;
    for (std::size_t i = 0; i < source.size(); ++i) {
      const Eigen::Vector3d p_source = source.points[i].cast<double>();
      const Eigen::Vector3f p = (r.T_target_source * p_source).cast<float>();
      const int j = tree.nearest(p, float(options.max_correspondence_m));
      if (j < 0) continue;
      const Eigen::Vector3d n_target = target.normals[j].cast<double>();
      const Eigen::Vector3d n_source =
          r.T_target_source.rotation() * source.normals[i].cast<double>();
      if (c.max_normal_angle_rad > 0 && n_target.dot(n_source) < std::cos(c.max_normal_angle_rad)) {
        ++left_out;
        continue;
      }
      const Eigen::Vector3d n =
          c.symmetric ? symmetric_pair_normal<double>(n_target, n_source) : n_target;
      own_normal += (n - n_target).norm() > 0.05;
      const double res =
          point_to_plane_residual(r.T_target_source, p_source, target.points[j].cast<double>(), n);
      const double w = robust_weight(options.kernel, options.kernel_scale_m, res);
      const Matrix16d J = point_to_plane_jacobian_right(r.T_target_source, p_source, n);
      H += w * J.transpose() * J;
      ++pairs;
      down_weighted += w < 0.5;
    }
    EXPECT_EQ(r.inliers, pairs);
    EXPECT_LT(pairs, int(source.size()) * 10 / 11 + 2);  // the 2 mm ones found no partner
    EXPECT_GT(down_weighted, int(source.size()) / 10);   // the 0.4 mm ones weigh about 1/4
    if (c.symmetric) {
      EXPECT_GT(own_normal, int(source.size()) / 8);  // the turned fifth, less the reversed
    } else {
      EXPECT_EQ(own_normal, 0);
    }
    if (c.max_normal_angle_rad > 0) {
      EXPECT_GT(left_out, int(source.size()) / 15);  // the reversed 13th
    }
    EXPECT_LT((r.hessian - H).norm(), 1e-5 * H.norm()) << r.hessian << "\n\n" << H;
  }
}

// Two samplings of a curved patch on grids half a spacing apart, as two frames of a small
// rounded contact: an ellipsoidal cap (radii of curvature 1 and 2.5 mm, like a rounded cube
// corner) sampled every 0.16 mm (the 120x160 pixel pitch) within 1.2 mm of its apex, moved by 6
// mrad and a few micrometres. The target's tangent plane misses the neighbouring samples of the
// curved surface by up to curvature x spacing^2 / 2 (~3 um), as much as the motion moves points;
// along the pair's mean normal two exact samples of such a surface are nearly level, so the
// symmetric objective's answer carries a fraction of the error of the target's normals alone.
TEST(IcpSymmetric, CurvedPatchOnShiftedGridsRegistersWithASmallerError) {
  const double h = 0.16e-3, rx = 1e-3, ry = 2.5e-3;
  const auto sample = [&](double ox, double oy) {
    PointCloud cloud;
    for (int a = -8; a <= 8; ++a) {
      for (int b = -8; b <= 8; ++b) {
        const double x = a * h + ox, y = b * h + oy;
        if (x * x + y * y > 0.6e-3 * 0.6e-3 * 4) continue;
        const Eigen::Vector3d p(x, y, x * x / (2 * rx) + y * y / (2 * ry));
        const Eigen::Vector3d n = Eigen::Vector3d(x / rx, y / ry, -1).normalized();
        cloud.push_back(p.cast<float>(), n.cast<float>());
      }
    }
    return cloud;
  };
  const PointCloud target = sample(0, 0);
  const PointCloudTree tree(target);
  const SE3 truth = SE3::exp((Vector6d() << 2e-6, -3e-6, 1e-6, 0.004, -0.003, 0.0030).finished());
  const PointCloud source = transform_cloud(truth.inverse(), sample(0.5 * h, 0.4 * h));
  double error[2] = {};
  for (const bool symmetric : {true, false}) {
    IcpOptions options;
    options.symmetric = symmetric;
    options.min_eigenvalue_ratio = 0;  // every direction solved: the objective decides
    const IcpResult r = PointToPlaneIcp(options).align(source, tree, SE3::Identity());
    ASSERT_TRUE(r.converged) << to_string(r.status);
    error[symmetric] = rotation_distance(r.T_target_source, truth);
    std::printf("  %-15s %zu points, rotation error %.3f mrad (motion 5.8 mrad), %.2f um\n",
                symmetric ? "symmetric" : "target normals", source.size(), error[symmetric] * 1e3,
                translation_distance(r.T_target_source, truth) * 1e6);
  }
  EXPECT_LT(error[1], 0.3e-3);
  EXPECT_LT(error[1], 0.5 * error[0]);
  // A source without normals has only the target's to offer: the same answer as without the
  // symmetric objective.
  PointCloud bare;
  bare.points = source.points;
  IcpOptions options;
  options.min_eigenvalue_ratio = 0;
  ASSERT_TRUE(options.symmetric);
  const IcpResult r = PointToPlaneIcp(options).align(bare, tree, SE3::Identity());
  ASSERT_TRUE(r.converged) << to_string(r.status);
  EXPECT_NEAR(rotation_distance(r.T_target_source, truth), error[0], 1e-9);
}

// A surface with sharp creases (a low pyramid: four faces 45-60 degrees apart), sampled on two
// grids half a pixel apart, as two frames sample a toy brick's stud rims. Nearest neighbours
// across a crease pair points of different faces, whose mean normal is neither face's; with the
// pairs' normals limited to 0.25 rad apart (the default) only same-face pairs are used.
TEST(IcpNormalsLimit, PairsAcrossACreaseAreLeftOutWithEitherObjective) {
  const double h = 0.16e-3, sx = 0.5, sy = 0.35;
  const auto sample = [&](double ox, double oy) {
    PointCloud cloud;
    for (int a = -10; a <= 10; ++a) {
      for (int b = -10; b <= 10; ++b) {
        const double x = a * h + ox, y = b * h + oy;
        const Eigen::Vector3d p(x, y, sx * std::abs(x) + sy * std::abs(y));
        const Eigen::Vector3d n =
            Eigen::Vector3d(x > 0 ? sx : -sx, y > 0 ? sy : -sy, -1).normalized();
        cloud.push_back(p.cast<float>(), n.cast<float>());
      }
    }
    return cloud;
  };
  const PointCloudTree tree(sample(0, 0));
  const SE3 truth = SE3::exp((Vector6d() << 2e-6, -3e-6, 1e-6, 0.004, -0.003, 0.006).finished());
  const PointCloud source = transform_cloud(truth.inverse(), sample(0.5 * h, 0.4 * h));
  for (const bool symmetric : {true, false}) {
    double error[2] = {};
    for (const bool limited : {false, true}) {
      IcpOptions options;
      options.symmetric = symmetric;
      if (!limited) options.max_normal_angle_rad = 0;
      const IcpResult r = PointToPlaneIcp(options).align(source, tree, SE3::Identity());
      ASSERT_TRUE(r.converged) << to_string(r.status);
      error[limited] = rotation_distance(r.T_target_source, truth);
      std::printf(
          "  %-9s %-19s %zu points, %d pairs, rotation error %.3f mrad (motion 7.8 mrad), "
          "%.2f um\n",
          symmetric ? "symmetric" : "target's", limited ? "normals within 0.25" : "every pair",
          source.size(), r.inliers, error[limited] * 1e3,
          translation_distance(r.T_target_source, truth) * 1e6);
    }
    EXPECT_LT(error[1], 0.5 * error[0]) << (symmetric ? "symmetric" : "target's normals");
  }
}

TEST(IcpBadInput, TooFewPointsOrNoOverlapIsNotConverged) {
  const PointCloud target = flat_patch(0.0001);
  const PointCloudTree tree(target);
  PointCloud few;
  for (int i = 0; i < 5; ++i) few.push_back(target.points[i], target.normals[i]);
  const SE3 guess = SE3::Translation({1e-4, 0, 0});
  const IcpResult a = PointToPlaneIcp().align(few, tree, guess);
  EXPECT_FALSE(a.converged);
  EXPECT_EQ(a.status, IcpStatus::kTooFewPoints);
  EXPECT_EQ(a.iterations, 0);
  EXPECT_LT(translation_distance(a.T_target_source, guess), 1e-15);
  // Empty clouds and a target without normals.
  EXPECT_EQ(PointToPlaneIcp().align(PointCloud(), tree, guess).status, IcpStatus::kTooFewPoints);
  PointCloud no_normals = target;
  no_normals.normals.clear();
  EXPECT_EQ(PointToPlaneIcp().align(target, PointCloudTree(no_normals), guess).status,
            IcpStatus::kTooFewPoints);
  EXPECT_EQ(PointToPlaneIcp().align(target, PointCloudTree(PointCloud()), guess).status,
            IcpStatus::kTooFewPoints);
  // A NaN source point (or normal), from a caller's own front end, is left out: the answer is
  // the cloud's without it (it had been NaN throughout).
  PointCloud with_nan = target;
  with_nan.points[7] = Eigen::Vector3f(NAN, 0, 0);
  with_nan.normals[11] = Eigen::Vector3f(0, NAN, 1);
  PointCloud without = target;
  without.points.erase(without.points.begin() + 11);
  without.normals.erase(without.normals.begin() + 11);
  without.points.erase(without.points.begin() + 7);
  without.normals.erase(without.normals.begin() + 7);
  const IcpResult nan_run = PointToPlaneIcp().align(with_nan, tree, guess);
  const IcpResult clean_run = PointToPlaneIcp().align(without, tree, guess);
  EXPECT_TRUE(is_finite(nan_run.T_target_source));
  EXPECT_EQ(nan_run.status, clean_run.status);
  EXPECT_EQ(nan_run.source_points, clean_run.source_points);
  EXPECT_LT(translation_distance(nan_run.T_target_source, clean_run.T_target_source), 1e-12);
  // A target tree refuses a NaN point, which would send its searches astray.
  EXPECT_THROW(PointCloudTree{with_nan}, std::invalid_argument);
  // Enough points, but 5 cm away: no correspondences.
  const IcpResult far = PointToPlaneIcp().align(target, tree, SE3::Translation({0.05, 0, 0}));
  EXPECT_FALSE(far.converged);
  EXPECT_EQ(far.status, IcpStatus::kTooFewCorrespondences);
}

TEST(IcpReuse, OneTreeServesManyCallsAndMostQueriesAreSkippedNearConvergence) {
  const PointCloud target = sphere_cap({0, 0, 0.005}, 0.006, 0.003, 0.00005);
  const PointCloudTree tree(target);
  IcpOptions options;
  options.max_iterations = 10;
  options.convergence_translation_m = 0;  // run all 10 iterations
  options.convergence_rotation_rad = 0;
  options.cycle_extent_m = 0;
  PointToPlaneIcp icp(options);
  PointCloud source = transform_cloud(SE3::Translation({0.0001, 0.00005, 0.0001}), target);
  const IcpResult first = icp.align(source, tree, SE3::Identity());
  const IcpResult second = icp.align(source, tree, SE3::Identity());
  EXPECT_EQ(first.iterations, 10);
  EXPECT_LT(translation_distance(first.T_target_source, second.T_target_source), 1e-12);
  EXPECT_LT(icp.last_queries(), long(3 * source.size())) << "of " << 10 * source.size();
}

// A bumpy, fully constrained surface z = A sin(x / l) sin(y / l) over side x side metres.
PointCloud bumpy_surface(double side_m, double spacing_m) {
  const double A = 0.0005, l = 0.0015;
  PointCloud c;
  const int n = int(side_m / spacing_m) + 1;
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      const double x = -side_m / 2 + a * spacing_m, y = -side_m / 2 + b * spacing_m;
      const double zx = A / l * std::cos(x / l) * std::sin(y / l);
      const double zy = A / l * std::sin(x / l) * std::cos(y / l);
      c.push_back(Eigen::Vector3f(float(x), float(y), float(A * std::sin(x / l) * std::sin(y / l))),
                  Eigen::Vector3d(-zx, -zy, 1).normalized().cast<float>());
    }
  }
  return c;
}

TEST(IcpCoarseToFine, SameAnswerAsTheFullCloudWithFewerQueries) {
  const PointCloudTree target(bumpy_surface(0.012, 0.00005));
  const SE3 truth = SE3::exp((Vector6d() << 2e-4, -1e-4, 1e-4, 0.01, -0.015, 0.02).finished());
  const PointCloud source = transform_cloud(truth.inverse(), bumpy_surface(0.008, 0.00007));
  IcpOptions options;
  options.kernel = RobustKernel::kNone;
  PointToPlaneIcp coarse(options);
  options.coarse_points = 0;
  PointToPlaneIcp full(options);
  const IcpResult a = coarse.align(source, target, SE3::Identity());
  const IcpResult b = full.align(source, target, SE3::Identity());
  ASSERT_TRUE(a.converged) << to_string(a.status);
  ASSERT_TRUE(b.converged) << to_string(b.status);
  EXPECT_GT(a.coarse_iterations, 0);
  EXPECT_EQ(b.coarse_iterations, 0);
  // The fine iterations decide: the same fixed point, every point an inlier, the same Hessian.
  EXPECT_LT(translation_distance(a.T_target_source, b.T_target_source), 1e-8);
  EXPECT_LT(rotation_distance(a.T_target_source, b.T_target_source), 1e-7);
  EXPECT_LT(translation_distance(a.T_target_source, truth), 1e-6);
  EXPECT_EQ(a.inliers, int(source.size()));
  EXPECT_EQ(a.inliers, b.inliers);
  EXPECT_LT((a.hessian - b.hessian).norm(), 1e-6 * b.hessian.norm());
  EXPECT_LT(coarse.last_queries(), full.last_queries() * 3 / 4)
      << coarse.last_queries() << " vs " << full.last_queries();
  std::printf("  coarse to fine: %d+%d iterations, %ld queries; full cloud: %d iterations, %ld\n",
              a.coarse_iterations, a.iterations - a.coarse_iterations, coarse.last_queries(),
              b.iterations, full.last_queries());
}

// The parallel sums are reduced in a fixed order, so a registration gives the same bits every
// time on two threads (with work-stealing reduction they differed by ~1e-12 from run to run,
// and a tracker amplified that on hard sequences).
TEST(IcpDeterminism, TheSameRegistrationGivesTheSameBitsOnTwoThreads) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, 2);
  const PointCloudTree target(bumpy_surface(0.012, 0.00005));
  const SE3 truth = SE3::exp((Vector6d() << 2e-4, -1e-4, 1e-4, 0.01, -0.015, 0.02).finished());
  const PointCloud source = transform_cloud(truth.inverse(), bumpy_surface(0.008, 0.00007));
  PointToPlaneIcp icp{IcpOptions()};
  const IcpResult first = icp.align(source, target, SE3::Identity());
  ASSERT_TRUE(first.converged) << to_string(first.status);
  for (int k = 0; k < 20; ++k) {
    const IcpResult again = icp.align(source, target, SE3::Identity());
    ASSERT_EQ(again.T_target_source.matrix(), first.T_target_source.matrix()) << "run " << k;
    ASSERT_EQ(again.hessian, first.hessian) << "run " << k;
  }
}

TEST(IcpCoarseToFine, TheLastIterationsAndSmallCloudsUseEveryPoint) {
  const PointCloudTree target(bumpy_surface(0.008, 0.00005));
  const SE3 truth = SE3::exp((Vector6d() << 2e-4, -1e-4, 1e-4, 0.01, -0.015, 0.02).finished());
  const PointCloud source = transform_cloud(truth.inverse(), bumpy_surface(0.004, 0.00007));
  IcpOptions options;
  options.max_iterations = 1;
  PointToPlaneIcp one(options);
  const IcpResult r = one.align(source, target, SE3::Identity());
  EXPECT_EQ(r.iterations, 1);
  EXPECT_EQ(r.coarse_iterations, 0);
  EXPECT_EQ(r.inliers, int(source.size()));
  // A coarse phase that never settles (threshold 0) gets at most half of the iterations.
  options = IcpOptions();
  options.max_iterations = 10;
  options.coarse_step_m = 0;
  PointToPlaneIcp unsettled(options);
  const IcpResult u = unsettled.align(source, target, SE3::Identity());
  EXPECT_EQ(u.coarse_iterations, 5);
  EXPECT_TRUE(u.converged) << to_string(u.status);
  EXPECT_EQ(u.inliers, int(source.size()));
  // Under twice coarse_points there is nothing to gain.
  options = IcpOptions();
  options.coarse_points = int(source.size()) / 2 + 1;
  PointToPlaneIcp small(options);
  EXPECT_EQ(small.align(source, target, SE3::Identity()).coarse_iterations, 0);
  // A subsample too sparse to find min_points partners hands over to the full cloud at once.
  options = IcpOptions();
  options.min_points = 600;
  PointToPlaneIcp sparse(options);
  const IcpResult s = sparse.align(source, target, SE3::Identity());
  EXPECT_TRUE(s.converged) << to_string(s.status);
  EXPECT_EQ(s.coarse_iterations, 1);
}

// Near its answer the iteration can fall into a cycle: nearest neighbours hand two or more poses
// back and forth, every step above the convergence thresholds, until the iteration limit, and the
// tracker then adds no factor. Of 80 small motions between renders of the toy brick and the
// cube corner at 120x160, a few cycle so; the cycle test (IcpOptions::cycle_extent_m) ends them
// converged where they were, in fewer iterations, and leaves the other registrations' answers
// where they were but for the last micrometre.
TEST(IcpCycles, ARegistrationInACycleConvergesWhereItWas) {
  const RenderCase brick = make_render_case("digit", mesh_shape("toy_brick.glb"));
  const RenderCase cube = make_render_case("digit", mesh_shape("cube.glb"));
  IcpOptions without;
  without.cycle_extent_m = 0;
  const double extent = IcpOptions().cycle_extent_m;
  std::mt19937 rng(3);
  int at_limit = 0, ended = 0;
  for (int k = 0; k < 40; ++k) {
    const SE3 delta = random_pose(rng, 1e-4, 0.01);
    for (const RenderCase* rc : {&brick, &cube}) {
      const TwoRenders tr =
          two_renders(*rc, rc == &brick ? brick_pose() : cube_corner_pose(), delta);
      const PointCloudTree target(tr.cloud_a);
      const IcpResult off = PointToPlaneIcp(without).align(tr.cloud_b, target, SE3::Identity());
      const IcpResult on = PointToPlaneIcp().align(tr.cloud_b, target, SE3::Identity());
      // The cycle test's distance: the source centroid's displacement plus its radius times the
      // angle.
      Eigen::Vector3d centre = Eigen::Vector3d::Zero();
      for (const auto& p : tr.cloud_b.points) centre += p.cast<double>();
      centre /= double(tr.cloud_b.size());
      double sq = 0;
      for (const auto& p : tr.cloud_b.points) sq += (p.cast<double>() - centre).squaredNorm();
      const double radius = std::sqrt(sq / double(tr.cloud_b.size()));
      const double apart = (off.T_target_source * centre - on.T_target_source * centre).norm() +
                           radius * rotation_distance(off.T_target_source, on.T_target_source);
      const std::string name =
          std::string(rc == &brick ? "toy brick" : "cube corner") + ", motion " + std::to_string(k);
      if (off.converged) {
        EXPECT_TRUE(on.converged) << name;
        EXPECT_LE(on.iterations, off.iterations) << name;
        EXPECT_LT(apart, extent) << name;
        continue;
      }
      ++at_limit;
      std::printf(
          "  %-22s at the limit (%d iterations); with the cycle test %s in %d, %.3f um "
          "from there\n",
          name.c_str(), off.iterations, to_string(on.status), on.iterations, apart * 1e6);
      if (!on.converged) continue;
      ++ended;
      EXPECT_LT(on.iterations, off.iterations) << name;
      // The last pose without the test is the cycle's next one.
      EXPECT_LT(apart, 2 * extent) << name;
    }
  }
  EXPECT_GT(at_limit, 0) << "no registration reached the limit: nothing was tested";
  EXPECT_GT(ended, 0);
}

}  // namespace
}  // namespace pg
