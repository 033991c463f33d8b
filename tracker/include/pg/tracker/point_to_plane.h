#pragma once
// The point-to-plane error term of the registrations in eq. 5 (image-to-image) and eq. 6
// (image-to-patch), its Jacobians, and the robust kernels that weight it.
#include <Eigen/Core>
#include <cmath>

#include "pg/core/se3.h"

namespace pg {

using Matrix16d = Eigen::Matrix<double, 1, 6>;

// r = n_t . (T_target_source p_s - q_t): the signed distance of the moved source point from the
// tangent plane of its corresponding target point q_t with unit normal n_t [m].
inline double point_to_plane_residual(const SE3& T_target_source, const Eigen::Vector3d& p_source,
                                      const Eigen::Vector3d& q_target,
                                      const Eigen::Vector3d& n_target) {
  return n_target.dot(T_target_source * p_source - q_target);
}

// The plane normal of a pair in the symmetric objective (IcpOptions::symmetric): the mean of the
// target point's normal and the moved source point's (R n_s), normalised; the target's alone when
// the two face apart (a mismatched pair, whose mean says nothing). With it, the residual and the
// Jacobians below are those of the plane through q_t with this normal, held fixed while
// linearising (the normal turns with T only to second order in the residual).
template <typename T>
Eigen::Matrix<T, 3, 1> symmetric_pair_normal(const Eigen::Matrix<T, 3, 1>& n_target,
                                             const Eigen::Matrix<T, 3, 1>& n_source_moved) {
  if (n_target.dot(n_source_moved) <= T(0)) return n_target;
  return (n_target + n_source_moved).normalized();
}

// Left perturbation T <- exp(delta) T, delta = [rho; phi] in the target frame about its origin:
//   exp(delta) p' ~= p' + rho + phi x p'  (p' = T p_s)
//   dr / d delta = [n^T, (p' x n)^T]      (n . (phi x p') = phi . (p' x n))
inline Matrix16d point_to_plane_jacobian_left(const SE3& T_target_source,
                                              const Eigen::Vector3d& p_source,
                                              const Eigen::Vector3d& n_target) {
  const Eigen::Vector3d p_target = T_target_source * p_source;
  Matrix16d J;
  J << n_target.transpose(), p_target.cross(n_target).transpose();
  return J;
}

// Right perturbation T <- T exp(eps), eps = [rho; phi] in the source frame:
//   T exp(eps) p_s ~= T p_s + R (rho + phi x p_s)
//   dr / d eps = [(R^T n)^T, (p_s x R^T n)^T]
inline Matrix16d point_to_plane_jacobian_right(const SE3& T_target_source,
                                               const Eigen::Vector3d& p_source,
                                               const Eigen::Vector3d& n_target) {
  const Eigen::Vector3d n_source = T_target_source.rotation().conjugate() * n_target;
  Matrix16d J;
  J << n_source.transpose(), p_source.cross(n_source).transpose();
  return J;
}

enum class RobustKernel {
  kNone,   // least squares
  kHuber,  // quadratic within the scale, linear beyond: w = min(1, c / |r|)
  kTukey,  // biweight: w = (1 - (r / c)^2)^2 within the scale, 0 beyond (rejects outliers)
};

// Iteratively-reweighted least-squares weight of residual r for kernel scale c [m].
inline double robust_weight(RobustKernel kernel, double scale_m, double r) {
  const double a = std::abs(r);
  switch (kernel) {
    case RobustKernel::kHuber:
      return a <= scale_m ? 1.0 : scale_m / a;
    case RobustKernel::kTukey: {
      if (a >= scale_m) return 0.0;
      const double s = 1.0 - (r / scale_m) * (r / scale_m);
      return s * s;
    }
    case RobustKernel::kNone:
    default:
      return 1.0;
  }
}

}  // namespace pg
