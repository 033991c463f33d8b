#pragma once
// Rigid-body transforms and the small amount of Lie-group math the project needs.
//
// Tangent vectors are ordered xi = [rho; phi]: translation part first, rotation part second, as in
// Sophus. T_a_b maps points from frame b to frame a. Everything is templated on the scalar so that
// Ceres' autodiff Jets pass through.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "pg/core/numbers.h"

namespace pg {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Vec6 = Eigen::Matrix<T, 6, 1>;
template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Below this squared angle [rad^2] the closed forms switch to their Taylor series.
constexpr double kSmallAngleSq = 1e-10;

template <typename T>
Mat3<T> hat(const Vec3<T>& w) {
  Mat3<T> K;
  K << T(0), -w.z(), w.y(), w.z(), T(0), -w.x(), -w.y(), w.x(), T(0);
  return K;
}

// SO(3) exponential as a unit quaternion.
template <typename T>
Eigen::Quaternion<T> so3_exp(const Vec3<T>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = phi.squaredNorm();
  T w, k;  // q = [w, k * phi]
  if (theta_sq < T(kSmallAngleSq)) {
    w = T(1) - theta_sq / T(8);
    k = T(0.5) - theta_sq / T(48);
  } else {
    const T theta = sqrt(theta_sq);
    w = cos(theta / T(2));
    k = sin(theta / T(2)) / theta;
  }
  return Eigen::Quaternion<T>(w, k * phi.x(), k * phi.y(), k * phi.z());
}

// SO(3) logarithm of a unit quaternion: the rotation vector with angle in [0, pi].
template <typename T>
Vec3<T> so3_log(const Eigen::Quaternion<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  // q and -q are the same rotation; pick w >= 0 so the angle is at most pi.
  const Eigen::Quaternion<T> q = q_in.w() < T(0) ? Eigen::Quaternion<T>(-q_in.coeffs()) : q_in;
  const Vec3<T> v = q.vec();
  const T n_sq = v.squaredNorm();
  if (n_sq < T(kSmallAngleSq)) {
    // atan2(n, w) / n = (1 / w) (1 - n^2 / (3 w^2)) + O(n^4)
    return T(2) / q.w() * (T(1) - n_sq / (T(3) * q.w() * q.w())) * v;
  }
  const T n = sqrt(n_sq);
  return T(2) * atan2(n, q.w()) / n * v;
}

// Left Jacobian of SO(3): exp(phi + d) ~= exp(Jl(phi) d) exp(phi). Also the V matrix of SE(3).
template <typename T>
Mat3<T> so3_left_jacobian(const Vec3<T>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = phi.squaredNorm();
  const Mat3<T> K = hat(phi);
  if (theta_sq < T(kSmallAngleSq)) {
    return Mat3<T>::Identity() + T(0.5) * K + K * K / T(6);
  }
  const T theta = sqrt(theta_sq);
  return Mat3<T>::Identity() + (T(1) - cos(theta)) / theta_sq * K +
         (theta - sin(theta)) / (theta_sq * theta) * K * K;
}

template <typename T>
Mat3<T> so3_left_jacobian_inverse(const Vec3<T>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = phi.squaredNorm();
  const Mat3<T> K = hat(phi);
  if (theta_sq < T(kSmallAngleSq)) {
    return Mat3<T>::Identity() - T(0.5) * K + K * K / T(12);
  }
  const T theta = sqrt(theta_sq);
  const T c = T(1) / theta_sq - (T(1) + cos(theta)) / (T(2) * theta * sin(theta));
  return Mat3<T>::Identity() - T(0.5) * K + c * K * K;
}

// Right Jacobians: exp(phi + d) ~= exp(phi) exp(Jr(phi) d); Jr(phi) = Jl(-phi).
template <typename T>
Mat3<T> so3_right_jacobian(const Vec3<T>& phi) {
  return so3_left_jacobian<T>(-phi);
}
template <typename T>
Mat3<T> so3_right_jacobian_inverse(const Vec3<T>& phi) {
  return so3_left_jacobian_inverse<T>(-phi);
}

// The coupling block Q(rho, phi) of SE(3)'s left Jacobian, Jl(xi) = [Jl(phi) Q; 0 Jl(phi)]
// (Barfoot, State Estimation for Robotics, eq. 7.86). Below an angle of 0.05 rad the
// coefficients are their Taylor series to theta^4: the closed forms cancel (the last one loses
// about 120 eps / theta^4 of its value: 1e-8 at 0.035 rad), the series' first neglected term is
// below 1e-12 of them there.
inline Eigen::Matrix3d se3_left_jacobian_q(const Eigen::Vector3d& rho, const Eigen::Vector3d& phi) {
  const double theta_sq = phi.squaredNorm();
  double c1, c2, c3;
  if (theta_sq < 0.05 * 0.05) {
    c1 = 1.0 / 6 - theta_sq / 120 + theta_sq * theta_sq / 5040;
    c2 = 1.0 / 24 - theta_sq / 720 + theta_sq * theta_sq / 40320;
    c3 = 1.0 / 120 - theta_sq / 2520 + theta_sq * theta_sq / 120960;
  } else {
    const double theta = std::sqrt(theta_sq), s = std::sin(theta), c = std::cos(theta);
    c1 = (theta - s) / (theta_sq * theta);
    c2 = (theta_sq + 2 * c - 2) / (2 * theta_sq * theta_sq);
    c3 = (2 * theta - 3 * s + theta * c) / (2 * theta_sq * theta_sq * theta);
  }
  const Eigen::Matrix3d P = hat<double>(rho), F = hat<double>(phi);
  const Eigen::Matrix3d FP = F * P, PF = P * F, FPF = FP * F;
  return 0.5 * P + c1 * (FP + PF + FPF) + c2 * (F * FP + PF * F - 3 * FPF) +
         c3 * (FPF * F + F * FPF);
}

// SE(3)'s inverse right Jacobian: log(exp(xi) exp(d)) ~= xi + Jr^-1(xi) d, the derivative of a
// factor's log error under a right perturbation. Jr(xi) = Jl(-xi), and
// Jl^-1 = [Jl^-1(phi), -Jl^-1(phi) Q Jl^-1(phi); 0, Jl^-1(phi)].
inline Matrix6d se3_right_jacobian_inverse(const Vector6d& xi) {
  const Eigen::Vector3d rho = -xi.head<3>(), phi = -xi.tail<3>();
  const Eigen::Matrix3d J_inv = so3_left_jacobian_inverse<double>(phi);
  Matrix6d out = Matrix6d::Zero();
  out.topLeftCorner<3, 3>() = J_inv;
  out.topRightCorner<3, 3>() = -J_inv * se3_left_jacobian_q(rho, phi) * J_inv;
  out.bottomRightCorner<3, 3>() = J_inv;
  return out;
}

template <typename T>
class SE3T {
 public:
  using Quat = Eigen::Quaternion<T>;

  SE3T() : q_(Quat::Identity()), t_(Vec3<T>::Zero()) {}
  // The quaternion is normalised here, so callers may pass any non-zero quaternion.
  SE3T(const Quat& q, const Vec3<T>& t) : q_(q.normalized()), t_(t) {}
  // R must be a rotation (to 1e-3, as a matrix of a few decimals is): a reflection (determinant
  // -1, a left-handed frame's) or a scaled matrix throws std::invalid_argument, instead of
  // becoming some other rotation. A non-finite R gives a non-finite pose (is_finite).
  SE3T(const Mat3<T>& R, const Vec3<T>& t) : q_(Quat(R).normalized()), t_(t) {
    if constexpr (std::is_floating_point_v<T>) {
      if (!R.allFinite()) return;
      const T off = (R.transpose() * R - Mat3<T>::Identity()).cwiseAbs().maxCoeff();
      const T det = R.determinant();
      if (off > T(1e-3) || det < T(0)) {
        throw std::invalid_argument(
            "SE3: the matrix is not a rotation (determinant " + std::to_string(double(det)) +
            ", R^T R off the identity by " + std::to_string(double(off)) +
            (det < T(0) ? "; a reflection: a left-handed frame's axes)" : ")"));
      }
    }
  }

  static SE3T Identity() { return SE3T(); }
  static SE3T Translation(const Vec3<T>& t) { return SE3T(Quat::Identity(), t); }

  // exp([rho; phi]) = (exp(phi), Jl(phi) rho).
  static SE3T exp(const Vec6<T>& xi) {
    const Vec3<T> rho = xi.template head<3>();
    const Vec3<T> phi = xi.template tail<3>();
    return SE3T(so3_exp<T>(phi), so3_left_jacobian<T>(phi) * rho);
  }

  Vec6<T> log() const {
    const Vec3<T> phi = so3_log<T>(q_);
    Vec6<T> xi;
    xi << so3_left_jacobian_inverse<T>(phi) * t_, phi;
    return xi;
  }

  SE3T inverse() const {
    const Quat q_inv = q_.conjugate();
    return SE3T(q_inv, -(q_inv * t_));
  }

  SE3T operator*(const SE3T& other) const { return SE3T(q_ * other.q_, q_ * other.t_ + t_); }
  Vec3<T> operator*(const Vec3<T>& p) const { return q_ * p + t_; }

  const Quat& rotation() const { return q_; }
  const Vec3<T>& translation() const { return t_; }
  Mat3<T> rotation_matrix() const { return q_.toRotationMatrix(); }

  Eigen::Matrix<T, 4, 4> matrix() const {
    Eigen::Matrix<T, 4, 4> M = Eigen::Matrix<T, 4, 4>::Identity();
    M.template topLeftCorner<3, 3>() = rotation_matrix();
    M.template topRightCorner<3, 1>() = t_;
    return M;
  }

  // Adjoint: T exp(xi) T^-1 = exp(Ad_T xi), for xi = [rho; phi].
  Eigen::Matrix<T, 6, 6> adjoint() const {
    const Mat3<T> R = rotation_matrix();
    Eigen::Matrix<T, 6, 6> A = Eigen::Matrix<T, 6, 6>::Zero();
    A.template topLeftCorner<3, 3>() = R;
    A.template topRightCorner<3, 3>() = hat<T>(t_) * R;
    A.template bottomRightCorner<3, 3>() = R;
    return A;
  }

  template <typename U>
  SE3T<U> cast() const {
    return SE3T<U>(q_.template cast<U>(), t_.template cast<U>());
  }

 private:
  Quat q_;
  Vec3<T> t_;
};

using SE3 = SE3T<double>;

// The paper's ominus: the tangent vector from A to B, log(A^-1 B).
template <typename T>
Vec6<T> ominus(const SE3T<T>& A, const SE3T<T>& B) {
  return (A.inverse() * B).log();
}

// Geodesic angle of a rotation [rad], in [0, pi].
inline double rotation_angle(const Eigen::Quaterniond& q) {
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}
// Geodesic rotation distance between two poses [rad].
inline double rotation_distance(const SE3& A, const SE3& B) {
  return rotation_angle(A.rotation().conjugate() * B.rotation());
}
inline double translation_distance(const SE3& A, const SE3& B) {
  return (A.translation() - B.translation()).norm();
}

// The unit quaternion of `xyzw` = (x, y, z, w) at any finite non-zero scale, or false when it has
// none (a non-finite or zero component vector). Scales by the largest component before
// normalising: the plain norm squares the components, so [1e200, 0, 0, 0] would overflow to an
// infinite norm and normalise to zero.
bool unit_quaternion(const Eigen::Vector4d& xyzw, Eigen::Quaterniond& q);

// Roll-pitch-yaw [rad] as R = Rz(yaw) Ry(pitch) Rx(roll) (rotations about the fixed x, y, z axes).
Eigen::Quaterniond quaternion_from_rpy(const Eigen::Vector3d& rpy);
Eigen::Vector3d rpy_from_quaternion(const Eigen::Quaterniond& q);
SE3 pose_from_position_rpy(const Eigen::Vector3d& position, const Eigen::Vector3d& rpy);

// Linear in translation, slerp in rotation; s in [0, 1].
SE3 interpolate(const SE3& A, const SE3& B, double s);

// Finite, and a rotation: its quaternion of unit length (a zero quaternion, ROS's unset pose,
// which the constructor cannot normalise, is not; nor one that overflowed or underflowed it).
bool is_finite(const SE3& T);

}  // namespace pg
