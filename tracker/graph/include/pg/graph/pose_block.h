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

using SE3Manifold = ceres::AutoDiffManifold<SE3RightPlus, kPoseBlockSize, kPoseTangentSize>;

}  // namespace pg
