#include <gtest/gtest.h>

#include <random>
#include <stdexcept>
#include <string>

#include "pg/core/se3.h"

namespace pg {
namespace {

// Seeded random poses, including angles near 0 and near pi where the closed forms are delicate.
std::vector<Vector6d> sample_tangents(int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vector6d> out;
  for (int i = 0; i < n; ++i) {
    Vector6d xi;
    for (int k = 0; k < 6; ++k) xi[k] = u(rng);
    const double scale = (i % 4 == 0) ? 1e-7 : (i % 4 == 1) ? 3.1 / xi.tail<3>().norm() : 1.0;
    xi.tail<3>() *= scale;
    out.push_back(xi);
  }
  return out;
}

::testing::AssertionResult near_vec(const Eigen::VectorXd& a, const Eigen::VectorXd& b,
                                    double tol) {
  const double err = (a - b).norm();
  if (err <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "error " << err << " > " << tol << "\n a = "
                                       << a.transpose() << "\n b = " << b.transpose();
}

TEST(SE3, ExpLogRoundTrip) {
  for (const auto& xi : sample_tangents(200, 1)) {
    EXPECT_TRUE(near_vec(SE3::exp(xi).log(), xi, 1e-9));
  }
}

TEST(SE3, LogExpRoundTrip) {
  for (const auto& xi : sample_tangents(200, 2)) {
    const SE3 T = SE3::exp(xi);
    const SE3 back = SE3::exp(T.log());
    EXPECT_TRUE(near_vec(back.matrix().reshaped(), T.matrix().reshaped(), 1e-9));
  }
}

TEST(SE3, InverseAndCompose) {
  for (const auto& xi : sample_tangents(100, 3)) {
    const SE3 T = SE3::exp(xi);
    EXPECT_TRUE(near_vec((T * T.inverse()).log(), Vector6d::Zero(), 1e-12));
    const Eigen::Vector3d p(0.1, -0.2, 0.3);
    EXPECT_TRUE(near_vec(T.inverse() * (T * p), p, 1e-12));
    EXPECT_TRUE(near_vec((T.matrix() * p.homogeneous()).head<3>(), T * p, 1e-12));
  }
}

TEST(SE3, OminusIsLogOfRelative) {
  const auto xs = sample_tangents(50, 4);
  for (std::size_t i = 1; i < xs.size(); ++i) {
    const SE3 A = SE3::exp(xs[i - 1]), B = SE3::exp(xs[i]);
    EXPECT_TRUE(near_vec(ominus(A, B), (A.inverse() * B).log(), 1e-12));
    EXPECT_TRUE(near_vec(ominus(A, A), Vector6d::Zero(), 1e-12));
    // B = A exp(ominus(A, B))
    const SE3 B2 = A * SE3::exp(ominus(A, B));
    EXPECT_TRUE(near_vec(B2.matrix().reshaped(), B.matrix().reshaped(), 1e-9));
  }
}

TEST(SE3, RotationAngleIsGeodesic) {
  for (double angle : {0.0, 1e-8, 0.3, 1.5, 3.0, 3.14159}) {
    const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -0.5).normalized();
    const SE3 A = SE3::exp((Vector6d() << 0.1, 0.2, 0.3, 0.4, -0.2, 0.1).finished());
    const SE3 B = A * SE3(so3_exp<double>(angle * axis), Eigen::Vector3d::Zero());
    EXPECT_NEAR(rotation_distance(A, B), angle, 1e-9);
    EXPECT_NEAR(rotation_distance(B, A), angle, 1e-9);
  }
}

TEST(SE3, AdjointConjugatesExp) {
  const auto xs = sample_tangents(60, 5);
  for (std::size_t i = 1; i < xs.size(); ++i) {
    const SE3 T = SE3::exp(xs[i - 1]);
    const Vector6d xi = 0.3 * xs[i];
    const SE3 lhs = T * SE3::exp(xi) * T.inverse();
    const SE3 rhs = SE3::exp(T.adjoint() * xi);
    EXPECT_TRUE(near_vec(lhs.matrix().reshaped(), rhs.matrix().reshaped(), 1e-9));
  }
}

// d/dd log(exp(phi) exp(d)) at d = 0 equals Jr^-1(phi); exp(phi + d) = exp(phi) exp(Jr d).
TEST(SO3, JacobiansMatchNumericDerivatives) {
  const double h = 1e-6;
  for (const auto& xi : sample_tangents(40, 6)) {
    Eigen::Vector3d phi = xi.tail<3>();
    if (phi.norm() > 3.0) phi *= 2.5 / phi.norm();  // stay clear of the pi cut of log
    Eigen::Matrix3d Jr_num, Jr_inv_num;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d d = h * Eigen::Vector3d::Unit(k);
      const auto q = so3_exp<double>(phi);
      Jr_num.col(k) = so3_log<double>(q.conjugate() * so3_exp<double>(phi + d)) / h -
                      so3_log<double>(q.conjugate() * so3_exp<double>(phi - d)) / h;
      Jr_num.col(k) *= 0.5;
      Jr_inv_num.col(k) = (so3_log<double>(q * so3_exp<double>(d)) -
                           so3_log<double>(q * so3_exp<double>(-d))) / (2 * h);
    }
    EXPECT_TRUE(near_vec(so3_right_jacobian<double>(phi).reshaped(), Jr_num.reshaped(), 1e-6));
    EXPECT_TRUE(near_vec(so3_right_jacobian_inverse<double>(phi).reshaped(),
                         Jr_inv_num.reshaped(), 1e-6));
    EXPECT_TRUE(near_vec((so3_left_jacobian<double>(phi) * so3_left_jacobian_inverse<double>(phi))
                             .reshaped(),
                         Eigen::Matrix3d::Identity().reshaped(), 1e-9));
  }
}

// d/dd log(exp(xi) exp(d)) at d = 0 equals SE(3)'s Jr^-1(xi): at random tangents (angles near
// 0 and up to 2.5 rad), on both sides of the series' switch at 0.05 rad, and at zero.
TEST(SE3, InverseRightJacobianMatchesNumericDerivatives) {
  std::vector<Vector6d> tangents = sample_tangents(40, 8);
  for (double angle : {0.0, 1e-9, 1e-4, 0.01, 0.049, 0.051, 0.2, 1.0}) {
    Vector6d xi;
    xi << 0.3, -0.8, 0.5, 0.6, -0.3, 0.74;
    xi.tail<3>() *= angle / xi.tail<3>().norm();
    tangents.push_back(xi);
  }
  const double h = 1e-6;
  for (Vector6d xi : tangents) {
    if (xi.tail<3>().norm() > 3.0) xi.tail<3>() *= 2.5 / xi.tail<3>().norm();
    const SE3 T = SE3::exp(xi);
    Matrix6d numeric;
    for (int k = 0; k < 6; ++k) {
      const Vector6d d = h * Vector6d::Unit(k);
      numeric.col(k) = ((T * SE3::exp(d)).log() - (T * SE3::exp(-d)).log()) / (2 * h);
    }
    EXPECT_TRUE(near_vec(se3_right_jacobian_inverse(xi).reshaped(), numeric.reshaped(), 1e-7))
        << "xi = " << xi.transpose();
  }
}

TEST(SE3, RpyRoundTripAndConvention) {
  const Eigen::Vector3d rpy(0.3, -0.7, 2.0);
  EXPECT_TRUE(near_vec(rpy_from_quaternion(quaternion_from_rpy(rpy)), rpy, 1e-12));
  // Pure yaw of 90 degrees turns +x into +y.
  const Eigen::Vector3d y = quaternion_from_rpy({0, 0, kPi / 2}) * Eigen::Vector3d::UnitX();
  EXPECT_TRUE(near_vec(y, Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(SE3, InterpolateEndsAndMidpoint) {
  const SE3 A = pose_from_position_rpy({0, 0, 0}, {0, 0, 0});
  const SE3 B = pose_from_position_rpy({0.01, 0.02, -0.03}, {0, 0, 1.0});
  EXPECT_TRUE(near_vec(interpolate(A, B, 0.0).log(), A.log(), 1e-12));
  EXPECT_TRUE(near_vec(interpolate(A, B, 1.0).log(), B.log(), 1e-12));
  const SE3 M = interpolate(A, B, 0.5);
  EXPECT_NEAR(rotation_distance(A, M), 0.5, 1e-12);
  EXPECT_TRUE(near_vec(M.translation(), Eigen::Vector3d(0.005, 0.01, -0.015), 1e-12));
}

// A rotation matrix is taken as it is; a reflection or a scaled matrix is refused (a reflection
// had become another rotation without a word).
TEST(SE3, ConstructorFromAMatrixTakesOnlyRotations) {
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const SE3 T(R, Eigen::Vector3d(1, 2, 3));
  EXPECT_LT((T.rotation_matrix() - R).cwiseAbs().maxCoeff(), 1e-12);
  // Four decimals, as a matrix typed in from a printout: taken.
  const Eigen::Matrix3d typed = (R * 1e4).array().round() / 1e4;
  EXPECT_LT(rotation_distance(SE3(typed, Eigen::Vector3d::Zero()), T), 1e-3);
  Eigen::Matrix3d mirrored = R;
  mirrored.col(2) *= -1;
  try {
    const SE3 bad(mirrored, Eigen::Vector3d::Zero());
    ADD_FAILURE() << "a reflection was taken: " << bad.rotation().coeffs().transpose();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("a reflection"), std::string::npos) << e.what();
  }
  EXPECT_THROW(SE3(2.0 * R, Eigen::Vector3d::Zero()), std::invalid_argument);
  Eigen::Matrix3d nan = R;
  nan(0, 0) = NAN;
  EXPECT_FALSE(is_finite(SE3(nan, Eigen::Vector3d::Zero())));
}

TEST(SE3, ConstructorNormalisesQuaternion) {
  const SE3 T(Eigen::Quaterniond(2, 0, 0, 0), Eigen::Vector3d::Zero());
  EXPECT_NEAR(T.rotation().norm(), 1.0, 1e-15);
  EXPECT_TRUE(is_finite(T));
  const SE3 bad(Eigen::Quaterniond::Identity(), Eigen::Vector3d(NAN, 0, 0));
  EXPECT_FALSE(is_finite(bad));
  // A zero quaternion (ROS's unset pose) cannot be normalised: no rotation, so no usable pose;
  // nor quaternions whose norm overflows or underflows.
  for (const Eigen::Quaterniond& q :
       {Eigen::Quaterniond(0, 0, 0, 0), Eigen::Quaterniond(1e200, 0, 0, 0),
        Eigen::Quaterniond(1e-200, 1e-200, 0, 0)}) {
    EXPECT_FALSE(is_finite(SE3(q, Eigen::Vector3d::Zero()))) << q.coeffs().transpose();
  }
}

}  // namespace
}  // namespace pg
