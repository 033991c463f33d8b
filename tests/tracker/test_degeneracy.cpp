// The degeneracy report's unconstrained twists: the span the data leave free, without the
// rotation slivers an eigen-solver mixes into a cluster of small eigenvalues.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "pg/tracker/degeneracy.h"

namespace pg {
namespace {

constexpr double kRatio = 5e-3;  // IcpOptions::min_eigenvalue_ratio's default
constexpr double kL = 3.75e-3;   // RMS distance of an edge's contact strip from its normal [m]

// Distance of v from the span of N's columns, relative to |v|.
double off_span(const Vector6d& v, const Matrix6Xd& N) {
  const Eigen::VectorXd a = N.colPivHouseholderQr().solve(v);
  return (N * a - v).norm() / v.norm();
}

// The scaled Hessian of a rounded edge along y, as the ICP sees it on a benchmark edge: the slide
// along y (0.01) and the turn about y (2.1) nearly free, the rest 220-930, and a slight coupling
// of the slide with the turn about z (a finite strip's ends), which tilts the slide's eigenvector
// by about 1e-3 towards that turn. Coordinates [rho_c; L phi].
Matrix6d edge_hessian(double slide_yaw_coupling) {
  Vector6d d;
  d << 930, 0.01, 600, 220, 2.1, 400;
  Matrix6d H = d.asDiagonal();
  H(1, 5) = H(5, 1) = slide_yaw_coupling;
  return H;
}

TEST(Degeneracy, EdgeSlideIsFreeWithoutTheEigenvectorsRotationSliver) {
  const DegeneracyReport report =
      analyse_degeneracy(edge_hessian(0.4), Eigen::Vector3d(0.001, 0.002, 0.012),
                         kL * Eigen::Matrix3d::Identity(), kRatio);
  ASSERT_EQ(report.unconstrained, 2);
  // The slide's eigenvector holds a turn about z of about 1e-3 (scaled): 0.27 rad per metre of
  // slide once divided by L, which a factor with sigma 1e-3 rad would pin.
  EXPECT_GT(std::abs(report.eigenvectors(5, 0)), 5e-4);
  const Matrix6Xd N = report.unconstrained_twists();
  ASSERT_EQ(N.cols(), 2);
  // The pure slide and the pure turn about y (about c) are in the span; nothing of z's turn is.
  const Vector6d slide = (Vector6d() << 0, 1, 0, 0, 0, 0).finished();
  const Vector6d turn = (Vector6d() << 0, 0, 0, 0, 1, 0).finished();
  EXPECT_LT(off_span(slide, N), 1e-9) << N;
  EXPECT_LT(off_span(turn, N), 1e-9) << N;
  EXPECT_LT(N.row(5).norm(), 1e-12) << N;
  // The twists at the origin are the same span moved by c.
  const Matrix6Xd N0 = report.unconstrained_twists_at_origin();
  const Matrix6d Ad = SE3::Translation(report.centre_target).adjoint();
  EXPECT_LT(off_span(Ad * slide, N0), 1e-9);
  EXPECT_LT(off_span(Ad * turn, N0), 1e-9);
}

// The step on an edge whose turn is constrained but whose slide is not: the slide's eigenvector
// borrows a little of the turn (scaled 0.008, as on the benchmark's cube edges: 16 rad per metre
// of slide once divided by the 0.5 mm extent about the edge). The least-rotation choice among
// equally good steps must not spend that sliver: it would cancel the measured turn by sliding.
TEST(Degeneracy, StepKeepsTheTurnAboutAnEdgeInsteadOfSlidingAlongIt) {
  const double l_turn = 0.5e-3;  // the contact's RMS distance from the edge [m]
  const Eigen::Matrix3d Lambda = Eigen::Vector3d(kL, l_turn, kL).asDiagonal();
  Vector6d d;
  d << 930, 0.01, 600, 220, 30, 400;  // rho_x, slide (rho_y), rho_z, tilt, turn about y, yaw
  Matrix6d H = d.asDiagonal();
  H(1, 4) = H(4, 1) = 0.25;
  const DegeneracyReport report = analyse_degeneracy(H, Eigen::Vector3d::Zero(), Lambda, kRatio);
  ASSERT_EQ(report.unconstrained, 1);
  EXPECT_GT(std::abs(report.eigenvectors(4, 0)), 5e-3) << "the slide carries a sliver of the turn";
  // The registration is off by a 20 mrad turn about y: g = -H x for x that turn, scaled.
  Vector6d x = Vector6d::Zero();
  x[4] = l_turn * 0.02;
  const Vector6d step = constrained_step(report, -H * x);
  EXPECT_NEAR(step[4], 0.02, 0.001) << step.transpose();
  EXPECT_LT(std::abs(step[1]), 1e-6) << "slide [m]: " << step.transpose();
  // The free direction handed on is the slide, without the turn.
  const Matrix6Xd N = report.unconstrained_twists();
  ASSERT_EQ(N.cols(), 1);
  EXPECT_LT(N.bottomRows<3>().norm(), 1e-12 * N.topRows<3>().norm()) << N.transpose();
}

// Lambda holds the points' RMS distance from each axis through their centroid: for a strip 15 mm
// long (x), 2 mm wide (y) and 0.5 mm deep (z), about 0.6 mm about x and 4.3 mm about y and z.
TEST(Degeneracy, RotationScaleIsTheRmsDistanceFromEachAxis) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 20000; ++i)
    points.emplace_back(0.015 * u(rng), 0.002 * u(rng), 0.0005 * u(rng));
  // Turned, so that the axes are not the frame's.
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (const auto& p : points) S += (R * p) * (R * p).transpose();
  S /= double(points.size());
  const Eigen::Matrix3d Lambda = rotation_scale(S);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d a = R.col(k);
    double sum = 0;
    for (const auto& p : points) sum += (R * p).cross(a).squaredNorm();
    const double rms_distance = std::sqrt(sum / double(points.size()));
    EXPECT_NEAR((Lambda * a).norm(), rms_distance, 1e-3 * rms_distance) << "axis " << k;
    EXPECT_NEAR(a.dot(Lambda * a), rms_distance, 1e-3 * rms_distance) << "axis " << k;
  }
  EXPECT_NEAR((Lambda * R.col(0)).norm(), 0.0006, 0.0001);
  // Points on a line: the turn about it is floored, not zero, so Lambda stays invertible.
  Eigen::Matrix3d line = Eigen::Matrix3d::Zero();
  line(0, 0) = 1e-5;
  const Eigen::Matrix3d L_line = rotation_scale(line);
  EXPECT_GT(L_line(0, 0), 0.0);
  EXPECT_TRUE(L_line.allFinite());
}

// Property: for random Hessians with a cluster of small eigenvalues, every cleaned direction
// still costs at most the threshold (ratio x largest eigenvalue) in scaled coordinates, and the
// cleaned twists span as many directions as were found free.
TEST(Degeneracy, CleanedDirectionsStayUnconstrained) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const int k = 1 + trial % 3;
    Matrix6d A;
    for (int i = 0; i < 36; ++i) A(i / 6, i % 6) = u(rng);
    const Matrix6d Q = Eigen::HouseholderQR<Matrix6d>(A).householderQ();
    Vector6d d;
    for (int i = 0; i < 6; ++i)
      d[i] = i < k ? 1e-3 * std::abs(u(rng)) : 100 + 900 * std::abs(u(rng));
    const Matrix6d H = Q * d.asDiagonal() * Q.transpose();
    const DegeneracyReport report =
        analyse_degeneracy(H, Eigen::Vector3d::Zero(), kL * Eigen::Matrix3d::Identity(), kRatio);
    ASSERT_EQ(report.unconstrained, k);
    const Matrix6Xd N = report.unconstrained_twists();
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(N);
    EXPECT_EQ(svd.rank(), k) << "trial " << trial;
    for (int i = 0; i < k; ++i) {
      Vector6d x = N.col(i);
      x.tail<3>() *= kL;  // back to scaled coordinates
      const double cost = x.dot(H * x) / x.squaredNorm();
      EXPECT_LE(cost, kRatio * report.eigenvalues[5]) << "trial " << trial << " direction " << i;
    }
  }
}

// A cloud registered against itself: what a shape leaves free. Samples 0.1 mm apart, normals
// exact.
TEST(Degeneracy, CloudDegeneracyCountsWhatEachShapeLeavesFree) {
  const auto grid = [](auto&& add) {
    for (int a = -15; a <= 15; ++a) {
      for (int b = -15; b <= 15; ++b) add(1e-4 * a, 1e-4 * b);
    }
  };
  PointCloud plane, cap, cylinder, corner;
  grid([&](double u, double v) { plane.push_back({float(u), float(v), 0.0f}, {0, 0, -1}); });
  const double R = 0.006;  // a sphere cap and a cylinder of radius R, their axis / centre at +z R
  grid([&](double u, double v) {
    const Eigen::Vector3d c_to_p(u, v, -std::sqrt(R * R - u * u - v * v));
    cap.push_back((c_to_p + Eigen::Vector3d(0, 0, R)).cast<float>(),
                  c_to_p.normalized().cast<float>());
  });
  grid([&](double u, double v) {
    const Eigen::Vector3d c_to_p(u, 0, -std::sqrt(R * R - u * u));  // axis along y
    cylinder.push_back((c_to_p + Eigen::Vector3d(0, v, R)).cast<float>(),
                       c_to_p.normalized().cast<float>());
  });
  grid([&](double u, double v) {  // three faces meeting at the origin
    if (u < 0 || v < 0) return;
    corner.push_back({float(u), float(v), 0}, {0, 0, -1});
    corner.push_back({float(u), 0, float(v)}, {0, -1, 0});
    corner.push_back({0, float(u), float(v)}, {-1, 0, 0});
  });
  EXPECT_EQ(analyse_cloud_degeneracy(plane, kRatio).unconstrained, 3) << "two slides and the yaw";
  EXPECT_EQ(analyse_cloud_degeneracy(cap, kRatio).unconstrained, 3) << "the three rotations";
  EXPECT_EQ(analyse_cloud_degeneracy(cylinder, kRatio).unconstrained, 2)
      << "the slide along the axis and the turn about it";
  EXPECT_EQ(analyse_cloud_degeneracy(corner, kRatio).unconstrained, 0);
  EXPECT_EQ(analyse_cloud_degeneracy(PointCloud(), kRatio).unconstrained, 6);
  // The report's directions are the shape's: the cylinder's free twists are the slide along y
  // and the turn about its axis (the line x = 0, z = R), as twists about the origin.
  const Matrix6Xd N = analyse_cloud_degeneracy(cylinder, kRatio).unconstrained_twists_at_origin();
  Vector6d slide = Vector6d::Zero(), turn = Vector6d::Zero();
  slide[1] = 1;
  turn << -R, 0, 0, 0, 1, 0;  // [-omega x q; omega] with omega = y, q = (0, 0, R)
  EXPECT_LT(off_span(slide, N), 1e-3);
  EXPECT_LT(off_span(turn, N), 1e-3);
}

// A cloud of a sphere's cap (radius R, centre at +z R, normals exact), 31 x 31 samples 0.4 mm
// apart (a 12 mm square, the size of a DIGIT contact), or R / 40 apart for a small sphere.
PointCloud sphere_cap(double R) {
  PointCloud cap;
  const double spacing = std::min(4e-4, R / 40);
  for (int a = -15; a <= 15; ++a) {
    for (int b = -15; b <= 15; ++b) {
      const double u = spacing * a, v = spacing * b;
      const Eigen::Vector3d c_to_p(u, v, -std::sqrt(R * R - u * u - v * v));
      cap.push_back((c_to_p + Eigen::Vector3d(0, 0, R)).cast<float>(),
                    c_to_p.normalized().cast<float>());
    }
  }
  return cap;
}

// The contact's shape operator: I / R for a sphere (about any point, the normals' sign aside),
// (I - a a^T) / R for a cylinder of axis a, zero for a plane.
TEST(Degeneracy, ContactShapeIsTheNormalsGradient) {
  const double R = 0.006;
  const PointCloud cap = sphere_cap(R);
  const ContactShape sphere = fit_contact_shape(cap.points, cap.normals);
  EXPECT_LT((sphere.shape_operator - Eigen::Matrix3d::Identity() / R).norm(), 1e-3 / R)
      << sphere.shape_operator;
  EXPECT_LT(sphere.mean_normal.z(), -0.9);  // outward, away from the centre
  PointCloud cylinder, plane;
  for (int a = -15; a <= 15; ++a) {
    for (int b = -15; b <= 15; ++b) {
      const double u = 2e-4 * a, v = 2e-4 * b;
      const Eigen::Vector3d c_to_p(u, 0, -std::sqrt(R * R - u * u));  // axis along y
      cylinder.push_back((c_to_p + Eigen::Vector3d(0, v, R)).cast<float>(),
                         (-c_to_p.normalized()).cast<float>());  // normals inward: K's sign too
      plane.push_back({float(u), float(v), 0.0f}, {0, 0, 1});
    }
  }
  Eigen::Matrix3d across = Eigen::Matrix3d::Identity();
  across(1, 1) = 0;
  const ContactShape rod = fit_contact_shape(cylinder.points, cylinder.normals);
  EXPECT_LT((rod.shape_operator + across / R).norm(), 1e-3 / R) << rod.shape_operator;
  EXPECT_LT(fit_contact_shape(plane.points, plane.normals).shape_operator.norm(), 1e-9);
  // Rotated with the cloud.
  const Eigen::Matrix3d Rz = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  EXPECT_LT((rod.rotated(Rz).shape_operator + Rz * across * Rz.transpose() / R).norm(), 1e-3 / R);
  EXPECT_EQ(fit_contact_shape({}, {}).shape_operator, Eigen::Matrix3d::Zero());
}

// A large sphere's nearly flat cap: its free directions are its rotations about the far centre,
// whose rolls carry as little rotation per slide as an edge's sliver (Lambda / R, 0.02 at
// 0.15 m). They must stay rolls, not become slides: the data see a slide of the centre (the
// contact's edge moves over the cap), and a factor graph handed the slide as free pins the
// roll's tilt instead.
TEST(Degeneracy, AFarCentresRollsStayRollsNotSlides) {
  for (const double R : {0.006, 0.15, 1.0}) {
    SCOPED_TRACE("radius " + std::to_string(R) + " m");
    const DegeneracyReport report = analyse_cloud_degeneracy(sphere_cap(R), kRatio);
    ASSERT_EQ(report.unconstrained, 3);
    const Matrix6Xd N = report.unconstrained_twists_at_origin();
    ASSERT_EQ(N.cols(), 3);
    for (int axis = 0; axis < 3; ++axis) {
      // The rotation about the centre q = (0, 0, R): [-omega x q; omega].
      Vector6d roll = Vector6d::Zero();
      roll.tail<3>() = Eigen::Vector3d::Unit(axis);
      roll.head<3>() = -Eigen::Vector3d::Unit(axis).cross(Eigen::Vector3d(0, 0, R));
      EXPECT_LT(off_span(roll, N), 1e-3) << "axis " << axis << "\n" << N;
    }
    for (int axis = 0; axis < 2; ++axis) {
      Vector6d slide = Vector6d::Zero();
      slide[axis] = 1;
      EXPECT_GT(off_span(slide, N), 0.5 / std::sqrt(1 + R * R)) << "axis " << axis << "\n" << N;
    }
  }
}

// Learned normals bend a flat face into a dome of centimetres' radius, whose rolls would turn
// every frame's tilt error into a slide. With flat_radius_m, three free directions rolling about
// a farther centre are a flat face's: the slides along the contact and the spin about its normal.
// A 6 mm ball keeps its rolls (167 rad of tilt per metre of slide, against 1 / 0.02 m = 50).
TEST(Degeneracy, AFlatRadiusReadsTheRollsOfAFartherCentreAsAFlatFacesSlides) {
  for (const double R : {0.006, 0.15, 1.0}) {
    SCOPED_TRACE("radius " + std::to_string(R) + " m");
    DegeneracyReport report = analyse_cloud_degeneracy(sphere_cap(R), kRatio);
    ASSERT_EQ(report.unconstrained, 3);
    report.flat_radius_m = 0.02;
    const Matrix6Xd N = report.unconstrained_twists_at_origin();
    ASSERT_EQ(N.cols(), 3);
    Vector6d spin = Vector6d::Zero();
    spin[5] = 1;  // about the z axis, through the cap's centroid
    EXPECT_LT(off_span(spin, N), 1e-3) << N;
    for (int axis = 0; axis < 2; ++axis) {
      Vector6d roll = Vector6d::Zero(), slide = Vector6d::Zero();
      roll.tail<3>() = Eigen::Vector3d::Unit(axis);
      roll.head<3>() = -Eigen::Vector3d::Unit(axis).cross(Eigen::Vector3d(0, 0, R));
      slide[axis] = 1;
      if (R < 0.02) {
        EXPECT_LT(off_span(roll, N), 1e-3) << "axis " << axis << "\n" << N;
        EXPECT_GT(off_span(slide, N), 0.5) << "axis " << axis << "\n" << N;
      } else {
        EXPECT_LT(off_span(slide, N), 1e-3) << "axis " << axis << "\n" << N;
        EXPECT_GT(off_span(roll, N), 0.5) << "axis " << axis << "\n" << N;
      }
    }
  }
}

// Several sensors on one object: what none of their contacts constrains. A face under the object
// and one at its side (normals z and x, 1 cm apart) leave only the slide along y between them;
// two opposite faces (a pinch) the same three directions as one; a corner nothing.
TEST(Degeneracy, CommonDirectionsAreWhatNoContactConstrains) {
  const auto face = [](const Eigen::Vector3d& centre, const Eigen::Vector3d& normal) {
    const Eigen::Vector3d u = normal.unitOrthogonal(), v = normal.cross(u);
    PointCloud cloud;
    for (int a = -15; a <= 15; ++a) {
      for (int b = -15; b <= 15; ++b) {
        cloud.push_back((centre + 1e-4 * (a * u + b * v)).cast<float>(), (-normal).cast<float>());
      }
    }
    return analyse_cloud_degeneracy(cloud, kRatio).unconstrained_twists_at_origin();
  };
  const Matrix6Xd below = face({0, 0, -0.01}, Eigen::Vector3d::UnitZ());
  const Matrix6Xd side = face({0.01, 0, 0}, -Eigen::Vector3d::UnitX());
  const Matrix6Xd above = face({0, 0, 0.01}, -Eigen::Vector3d::UnitZ());
  ASSERT_EQ(below.cols(), 3);
  EXPECT_EQ(common_unconstrained_directions({below}), 3);
  EXPECT_EQ(common_unconstrained_directions({below, side}), 1);
  EXPECT_EQ(common_unconstrained_directions({below, above}), 3);
  EXPECT_EQ(common_unconstrained_directions({below, side, above}), 1);
  EXPECT_EQ(common_unconstrained_directions({below, Matrix6Xd(6, 0)}), 0);
  EXPECT_EQ(common_unconstrained_directions({}), 6);
}

}  // namespace
}  // namespace pg
