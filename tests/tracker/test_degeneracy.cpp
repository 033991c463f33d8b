// The degeneracy report's unconstrained twists: the span the data leave free, without the
// rotation slivers an eigen-solver mixes into a cluster of small eigenvalues.
#include <gtest/gtest.h>

#include <random>

#include "pg/tracker/degeneracy.h"

namespace pg {
namespace {

constexpr double kRatio = 5e-3;  // IcpOptions::min_eigenvalue_ratio's default
constexpr double kL = 3.75e-3;   // RMS radius of an edge's contact strip [m]

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
      analyse_degeneracy(edge_hessian(0.4), Eigen::Vector3d(0.001, 0.002, 0.012), kL, kRatio);
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
    const DegeneracyReport report = analyse_degeneracy(H, Eigen::Vector3d::Zero(), kL, kRatio);
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

}  // namespace
}  // namespace pg
