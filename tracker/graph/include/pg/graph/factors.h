#pragma once
// The PatchGraph factors (paper section IV-C, eq. 5-9) as Ceres autodiff functors.
//
// Variables: object poses o_t = T_world_object and sensor (end-effector) poses e_t =
// T_world_sensor. Every factor compares a pose predicted from the variables with a measured one,
// r = S log(T_meas^-1 T_pred), where S is the square root of the factor's 6x6 information
// (r in the right tangent space of T_meas, [rho; phi]).
#include <ceres/autodiff_cost_function.h>

#include <array>

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

// The motion priors below hold the object's pose x = F^-1 o in a reference frame F: the world
// (F = identity, as in the paper), or, while the object is held in contact, the sensor at its
// measured pose: in in-hand manipulation the object moves with the hand, and its motion relative
// to the hand is what is smooth; in the world frame these priors resist every acceleration of
// the hand. The two are the same for a still sensor (GraphOptions::motion_frame). The measured
// sensor pose stands for the estimated one: the end-effector prior holds them within its sigma
// (1e-5), a thousandth of these priors' own, and the factors stay functions of the object poses
// alone.
namespace detail {
template <typename T>
SE3T<T> in_frame(const SE3& T_frame_world, const T* o) {
  return T_frame_world.cast<T>() * pose_from_block(o);
}
}  // namespace detail

// Eq. 7, constant velocity: the body-frame motion x_{t-2} -> x_{t-1} repeats as x_{t-1} -> x_t,
// r = S log((x_{t-2}^-1 x_{t-1})^-1 (x_{t-1}^-1 x_t)).
struct ConstantVelocityFactor {
  Matrix6d sqrt_info;
  std::array<SE3, 3> T_frame_world;  // F^-1 of each pose, oldest first
  template <typename T>
  bool operator()(const T* o0, const T* o1, const T* o2, T* r) const {
    const SE3T<T> a = detail::in_frame(T_frame_world[0], o0);
    const SE3T<T> b = detail::in_frame(T_frame_world[1], o1);
    const SE3T<T> c = detail::in_frame(T_frame_world[2], o2);
    detail::whiten(sqrt_info, (a.inverse() * b).inverse() * (b.inverse() * c), r);
    return true;
  }
  static ceres::CostFunction* create(const Matrix6d& sqrt_info,
                                     const std::array<SE3, 3>& T_frame_world = {}) {
    return new ceres::AutoDiffCostFunction<ConstantVelocityFactor, 6, 7, 7, 7>(
        new ConstantVelocityFactor{sqrt_info, T_frame_world});
  }
};

// Not in the paper: a weak zero-velocity prior, r = S log(x_{t-1}^-1 x_t). Along directions no
// measurement sees (an edge's axis, a sphere's rotation) the velocity prior alone would let any
// velocity that once entered continue for ever; this one lets it decay instead.
struct VelocityDampingFactor {
  Matrix6d sqrt_info;
  std::array<SE3, 2> T_frame_world;
  template <typename T>
  bool operator()(const T* o0, const T* o1, T* r) const {
    detail::whiten(
        sqrt_info,
        detail::in_frame(T_frame_world[0], o0).inverse() * detail::in_frame(T_frame_world[1], o1),
        r);
    return true;
  }
  static ceres::CostFunction* create(const Matrix6d& sqrt_info,
                                     const std::array<SE3, 2>& T_frame_world = {}) {
    return new ceres::AutoDiffCostFunction<VelocityDampingFactor, 6, 7, 7>(
        new VelocityDampingFactor{sqrt_info, T_frame_world});
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
