#pragma once
// Poses as Ceres parameter blocks, and the SE(3) manifold they live on.
//
// A block holds T_world_x as [tx, ty, tz, qx, qy, qz, qw]. The manifold perturbs on the right,
// x [+] delta = x * exp(delta) with delta = [rho; phi] (se3.h's tangent order), so a factor's
// tangent-space residual and the solver's steps are both in the body frame of the pose.
#include <ceres/autodiff_manifold.h>

#include "pg/core/se3.h"

namespace pg {

constexpr int kPoseBlockSize = 7;
constexpr int kPoseTangentSize = 6;

template <typename T>
SE3T<T> pose_from_block(const T* b) {
  return SE3T<T>(Eigen::Quaternion<T>(b[6], b[3], b[4], b[5]), Vec3<T>(b[0], b[1], b[2]));
}

template <typename T>
void pose_to_block(const SE3T<T>& pose, T* b) {
  const auto& t = pose.translation();
  const auto& q = pose.rotation();
  b[0] = t.x();
  b[1] = t.y();
  b[2] = t.z();
  b[3] = q.x();
  b[4] = q.y();
  b[5] = q.z();
  b[6] = q.w();
}

struct SE3RightPlus {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* x_plus_delta) const {
    const Vec6<T> d = Eigen::Map<const Vec6<T>>(delta);
    pose_to_block(pose_from_block(x) * SE3T<T>::exp(d), x_plus_delta);
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* y_minus_x) const {
    Eigen::Map<Vec6<T>> out(y_minus_x);
    out = ominus(pose_from_block(x), pose_from_block(y));
    return true;
  }
};

// q (x) [v; 0] = Q(q) v: how a unit quaternion's coordinates (rows qx, qy, qz, qw) move when it
// turns by q exp(phi), twice their derivative in phi. Its columns are orthonormal.
inline Eigen::Matrix<double, 4, 3> quaternion_turns(const Eigen::Quaterniond& q) {
  Eigen::Matrix<double, 4, 3> Q;
  Q << q.w(), -q.z(), q.y(),  //
      q.z(), q.w(), -q.x(),   //
      -q.y(), q.x(), q.w(),   //
      -q.x(), -q.y(), -q.z();
  return Q;
}

// The manifold of the pose blocks: SE3RightPlus's Plus and Minus, with Plus's Jacobian written
// out. Ceres asks for that Jacobian for every block at every solver iteration; differentiated
// automatically (through exp, the quaternion product and its normalisation) it cost 12-24 % of
// the tracker's per-frame update. Minus's Jacobian, which the solver does not use, stays
// automatic.
class SE3Manifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kPoseBlockSize; }
  int TangentSize() const override { return kPoseTangentSize; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    return SE3RightPlus().Plus(x, delta, x_plus_delta);
  }
  // d(x [+] delta) / d delta at delta = 0, row-major 7 x 6, with q the block's quaternion
  // normalised (as Plus normalises it): the translation moves by R(q) rho, the quaternion by
  // q (x) [phi / 2; 0], which is already orthogonal to q (so the normalisation of the result does
  // not change it).
  bool PlusJacobian(const double* x, double* jacobian) const override {
    const Eigen::Quaterniond q = pose_from_block(x).rotation();
    Eigen::Map<Eigen::Matrix<double, kPoseBlockSize, kPoseTangentSize, Eigen::RowMajor>> J(
        jacobian);
    J.setZero();
    J.topLeftCorner<3, 3>() = q.toRotationMatrix();
    J.bottomRightCorner<4, 3>() = 0.5 * quaternion_turns(q);
    return true;
  }
  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    return SE3RightPlus().Minus(y, x, y_minus_x);
  }
  bool MinusJacobian(const double* x, double* jacobian) const override {
    return automatic_.MinusJacobian(x, jacobian);
  }

 private:
  ceres::AutoDiffManifold<SE3RightPlus, kPoseBlockSize, kPoseTangentSize> automatic_;
};

}  // namespace pg
