#pragma once
// The PatchGraph factors (paper section IV-C, eq. 5-9) as Ceres autodiff functors.
//
// Variables: object poses o_t = T_world_object and sensor (end-effector) poses e_t =
// T_world_sensor. Every factor compares a pose predicted from the variables with a measured one,
// r = S log(T_meas^-1 T_pred), where S is the square root of the factor's 6x6 information
// (r in the right tangent space of T_meas, [rho; phi]).
#include <ceres/autodiff_cost_function.h>

#include "pg/graph/pose_block.h"

namespace pg {

namespace detail {
template <typename T>
void whiten(const Matrix6d& sqrt_info, const SE3T<T>& T_meas_inv_pred, T* residual) {
  Eigen::Map<Vec6<T>> r(residual);
  r = sqrt_info.cast<T>() * T_meas_inv_pred.log();
}
}  // namespace detail

// Eq. 5, image-to-image: ICP of the current cloud (source) against the previous one (target)
// measures T_prev_cur = T_{S_{t-1}} <- T_{S_t} for points on the object: with
// T_sensor_object = e^-1 o, the prediction is (e_{t-1}^-1 o_{t-1}) (e_t^-1 o_t)^-1.
struct ImageToImageFactor {
  SE3 T_prev_cur;
  Matrix6d sqrt_info;

  template <typename T>
  bool operator()(const T* o_prev, const T* e_prev, const T* o_cur, const T* e_cur, T* r) const {
    const SE3T<T> T_sp_o = pose_from_block(e_prev).inverse() * pose_from_block(o_prev);
    const SE3T<T> T_sc_o = pose_from_block(e_cur).inverse() * pose_from_block(o_cur);
    detail::whiten(sqrt_info, T_prev_cur.cast<T>().inverse() * (T_sp_o * T_sc_o.inverse()), r);
    return true;
  }
  static ceres::CostFunction* create(const SE3& T_prev_cur, const Matrix6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<ImageToImageFactor, 6, 7, 7, 7, 7>(
        new ImageToImageFactor{T_prev_cur, sqrt_info});
  }
};

// Eq. 6, image-to-patch: ICP of the current cloud (source, sensor frame) against the local patch
// (target, object frame) measures T_object_sensor; the prediction is o_t^-1 e_t.
struct ImageToPatchFactor {
  SE3 T_object_sensor;
  Matrix6d sqrt_info;

  template <typename T>
  bool operator()(const T* o, const T* e, T* r) const {
    const SE3T<T> pred = pose_from_block(o).inverse() * pose_from_block(e);
    detail::whiten(sqrt_info, T_object_sensor.cast<T>().inverse() * pred, r);
    return true;
  }
  static ceres::CostFunction* create(const SE3& T_object_sensor, const Matrix6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<ImageToPatchFactor, 6, 7, 7>(
        new ImageToPatchFactor{T_object_sensor, sqrt_info});
  }
};

// Eq. 7, constant velocity: the body-frame motion o_{t-2} -> o_{t-1} repeats as o_{t-1} -> o_t,
// r = S log((o_{t-2}^-1 o_{t-1})^-1 (o_{t-1}^-1 o_t)).
struct ConstantVelocityFactor {
  Matrix6d sqrt_info;

  template <typename T>
  bool operator()(const T* o0, const T* o1, const T* o2, T* r) const {
    const SE3T<T> a = pose_from_block(o0), b = pose_from_block(o1), c = pose_from_block(o2);
    detail::whiten(sqrt_info, (a.inverse() * b).inverse() * (b.inverse() * c), r);
    return true;
  }
  static ceres::CostFunction* create(const Matrix6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<ConstantVelocityFactor, 6, 7, 7, 7>(
        new ConstantVelocityFactor{sqrt_info});
  }
};

// Not in the paper: a weak zero-velocity prior, r = S log(o_{t-1}^-1 o_t). Along directions no
// measurement sees (an edge's axis, a sphere's rotation) the velocity prior alone would let any
// velocity that once entered continue for ever; this one lets it decay instead.
struct VelocityDampingFactor {
  Matrix6d sqrt_info;

  template <typename T>
  bool operator()(const T* o0, const T* o1, T* r) const {
    detail::whiten(sqrt_info, pose_from_block(o0).inverse() * pose_from_block(o1), r);
    return true;
  }
  static ceres::CostFunction* create(const Matrix6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<VelocityDampingFactor, 6, 7, 7>(
        new VelocityDampingFactor{sqrt_info});
  }
};

// Eq. 8 (end-effector prior on e_t) and eq. 9 (vision prior on the first o_t of an episode):
// r = S log(T_meas^-1 x).
struct PosePriorFactor {
  SE3 T_meas;
  Matrix6d sqrt_info;

  template <typename T>
  bool operator()(const T* x, T* r) const {
    detail::whiten(sqrt_info, T_meas.cast<T>().inverse() * pose_from_block(x), r);
    return true;
  }
  static ceres::CostFunction* create(const SE3& T_meas, const Matrix6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<PosePriorFactor, 6, 7>(
        new PosePriorFactor{T_meas, sqrt_info});
  }
};

// S for an isotropic sigma on all six axes ([m] and [rad] alike, as in the paper).
inline Matrix6d isotropic_sqrt_info(double sigma) { return Matrix6d::Identity() / sigma; }

// S with S^T S = information, for a symmetric positive semi-definite information matrix
// (directions with zero information get zero rows).
Matrix6d sqrt_information(const Matrix6d& information);

}  // namespace pg
