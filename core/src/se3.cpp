#include "pg/core/se3.h"

#include <algorithm>
#include <cmath>

namespace pg {

bool unit_quaternion(const Eigen::Vector4d& xyzw, Eigen::Quaterniond& q) {
  const double largest = xyzw.cwiseAbs().maxCoeff();
  if (!xyzw.allFinite() || largest == 0.0) return false;
  const Eigen::Vector4d unit = (xyzw / largest).normalized();
  q = Eigen::Quaterniond(unit[3], unit[0], unit[1], unit[2]);
  return true;
}

Eigen::Quaterniond quaternion_from_rpy(const Eigen::Vector3d& rpy) {
  return Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX());
}

Eigen::Vector3d rpy_from_quaternion(const Eigen::Quaterniond& q) {
  const Eigen::Matrix3d R = q.normalized().toRotationMatrix();
  // R = Rz(y) Ry(p) Rx(r): R(2,0) = -sin(p).
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  double roll, yaw;
  if (std::abs(R(2, 0)) < 1.0 - 1e-12) {
    roll = std::atan2(R(2, 1), R(2, 2));
    yaw = std::atan2(R(1, 0), R(0, 0));
  } else {  // gimbal lock: only roll - yaw (or roll + yaw) is defined; put it all in yaw
    roll = 0.0;
    yaw = std::atan2(-R(0, 1), R(1, 1));
  }
  return {roll, pitch, yaw};
}

SE3 pose_from_position_rpy(const Eigen::Vector3d& position, const Eigen::Vector3d& rpy) {
  return SE3(quaternion_from_rpy(rpy), position);
}

SE3 interpolate(const SE3& A, const SE3& B, double s) {
  return SE3(A.rotation().slerp(s, B.rotation()),
             (1.0 - s) * A.translation() + s * B.translation());
}

bool is_finite(const SE3& T) {
  return T.translation().allFinite() && T.rotation().coeffs().allFinite() &&
         std::abs(T.rotation().squaredNorm() - 1.0) < 1e-6;
}

}  // namespace pg
