#pragma once
// The PatchGraph factors (paper section IV-C, eq. 5-9) as Ceres cost functions with their
// Jacobians written out.
//
// Variables: object poses o_t = T_world_object and sensor (end-effector) poses e_t =
// T_world_sensor. Every factor compares a pose predicted from the variables with a measured one,
// r = S log(E), E = T_meas^-1 T_pred, where S is the square root of the factor's 6x6
// information (r in the right tangent space of T_meas, [rho; phi]).
//
// Jacobians. Each pose enters E once, as itself or its inverse (the velocity prior's middle pose
// twice), so moving block k to x_k exp(d) moves E to E exp(M_k d) with M_k an adjoint: for
// E = A x B, M = Ad(B^-1); for E = A x^-1 B, M = -Ad(B^-1 x). Then dr/dd = S Jr^-1(log E) M_k.
// Ceres asks for dr/dx in the block's 7 coordinates (and multiplies it by the manifold's
// PlusJacobian P = [R 0; 0 Q/2], pose_block.h, to get dr/dd). r does not depend on the
// quaternion's length (pose_from_block normalises it), and Q's columns are orthonormal and
// orthogonal to q, so dr/dx = dr/dd [R^T 0; 0 2 Q^T] exactly.
// Until 2026-11-30 these were autodiff functors: a factor of four blocks carried 28-wide jets
// through its exp, log and products (test: Factors.ZeroAtTheTruthWithJacobiansMatchingNumericOnes).
#include <ceres/sized_cost_function.h>

#include <array>

#include "pg/graph/pose_block.h"

namespace pg {

namespace detail {

// r = S log(E), and where Ceres asks for them the Jacobians from the blocks' M_k (above). M is
// called with k only for the blocks whose Jacobian is asked for.
template <std::size_t kBlocks, class Adjoints>
bool log_error(const SE3& E, const Matrix6d& S, double const* const* x, double* residual,
               double** jacobians, const Adjoints& M) {
  const Vector6d e = E.log();
  Eigen::Map<Vector6d> r(residual);
  r = S * e;
  if (jacobians == nullptr) return true;
  const Matrix6d SJ = S * se3_right_jacobian_inverse(e);
  for (std::size_t k = 0; k < kBlocks; ++k) {
    if (jacobians[k] == nullptr) continue;
    const Matrix6d J_tangent = SJ * M(k);
    const Eigen::Quaterniond q = pose_from_block(x[k]).rotation();
    Eigen::Map<Eigen::Matrix<double, 6, kPoseBlockSize, Eigen::RowMajor>> J(jacobians[k]);
    J.leftCols<3>() = J_tangent.leftCols<3>() * q.toRotationMatrix().transpose();
    J.rightCols<4>() = 2.0 * J_tangent.rightCols<3>() * quaternion_turns(q).transpose();
  }
  return true;
}

}  // namespace detail

// Eq. 5, image-to-image: ICP of the current cloud (source) against the previous one (target)
// measures T_prev_cur = T_{S_{t-1}} <- T_{S_t} for points on the object: with
// T_sensor_object = e^-1 o, the prediction is (e_{t-1}^-1 o_{t-1}) (e_t^-1 o_t)^-1, so
// E = T_meas^-1 e_{t-1}^-1 o_{t-1} o_t^-1 e_t. Blocks: o_{t-1}, e_{t-1}, o_t, e_t.
class ImageToImageFactor final : public ceres::SizedCostFunction<6, 7, 7, 7, 7> {
 public:
  ImageToImageFactor(const SE3& T_prev_cur, const Matrix6d& sqrt_info)
      : T_cur_prev_(T_prev_cur.inverse()), sqrt_info_(sqrt_info) {}
  bool Evaluate(double const* const* x, double* r, double** jacobians) const override {
    const SE3 T_sp_o = pose_from_block(x[1]).inverse() * pose_from_block(x[0]);
    const SE3 T_sc_o = pose_from_block(x[3]).inverse() * pose_from_block(x[2]);
    const auto M = [&](std::size_t k) -> Matrix6d {
      switch (k) {
        case 0:
          return T_sc_o.adjoint();
        case 1:
          return -(T_sc_o * T_sp_o.inverse()).adjoint();
        case 2:
          return -T_sc_o.adjoint();
        default:
          return Matrix6d::Identity();
      }
    };
    const SE3 E = T_cur_prev_ * (T_sp_o * T_sc_o.inverse());
    return detail::log_error<4>(E, sqrt_info_, x, r, jacobians, M);
  }
  static ceres::CostFunction* create(const SE3& T_prev_cur, const Matrix6d& sqrt_info) {
    return new ImageToImageFactor(T_prev_cur, sqrt_info);
  }

 private:
  SE3 T_cur_prev_;
  Matrix6d sqrt_info_;
};

// Eq. 6, image-to-patch: ICP of the current cloud (source, sensor frame) against the local patch
// (target, object frame) measures T_object_sensor; the prediction is o_t^-1 e_t. Blocks: o_t,
// e_t.
class ImageToPatchFactor final : public ceres::SizedCostFunction<6, 7, 7> {
 public:
  ImageToPatchFactor(const SE3& T_object_sensor, const Matrix6d& sqrt_info)
      : T_sensor_object_(T_object_sensor.inverse()), sqrt_info_(sqrt_info) {}
  bool Evaluate(double const* const* x, double* r, double** jacobians) const override {
    const SE3 T_sensor_object = pose_from_block(x[1]).inverse() * pose_from_block(x[0]);
    const auto M = [&](std::size_t k) -> Matrix6d {
      if (k == 0) return -T_sensor_object.adjoint();
      return Matrix6d::Identity();
    };
    const SE3 E = T_sensor_object_ * T_sensor_object.inverse();
    return detail::log_error<2>(E, sqrt_info_, x, r, jacobians, M);
  }
  static ceres::CostFunction* create(const SE3& T_object_sensor, const Matrix6d& sqrt_info) {
    return new ImageToPatchFactor(T_object_sensor, sqrt_info);
  }

 private:
  SE3 T_sensor_object_;  // the measurement, inverted
  Matrix6d sqrt_info_;
};

// The motion priors below hold the object's pose x = F^-1 o in a reference frame F: the world
// (F = identity, as in the paper), or, while the object is held in contact, the sensor at its
// measured pose: in in-hand manipulation the object moves with the hand, and its motion relative
// to the hand is what is smooth; in the world frame these priors resist every acceleration of
// the hand. The two are the same for a still sensor (GraphOptions::motion_frame). The measured
// sensor pose stands for the estimated one: the end-effector prior holds them within its sigma
// (1e-5), a thousandth of these priors' own, and the factors stay functions of the object poses
// alone. (x moves as o does: F^-1 o exp(d) = x exp(d).)

// Eq. 7, constant velocity: the body-frame motion x_{t-2} -> x_{t-1} repeats as x_{t-1} -> x_t,
// r = S log((x_{t-2}^-1 x_{t-1})^-1 (x_{t-1}^-1 x_t)), E = x_{t-1}^-1 x_{t-2} x_{t-1}^-1 x_t.
class ConstantVelocityFactor final : public ceres::SizedCostFunction<6, 7, 7, 7> {
 public:
  ConstantVelocityFactor(const Matrix6d& sqrt_info, const std::array<SE3, 3>& T_frame_world)
      : sqrt_info_(sqrt_info), T_frame_world_(T_frame_world) {}
  bool Evaluate(double const* const* x, double* r, double** jacobians) const override {
    const SE3 a = T_frame_world_[0] * pose_from_block(x[0]);
    const SE3 b = T_frame_world_[1] * pose_from_block(x[1]);
    const SE3 c = T_frame_world_[2] * pose_from_block(x[2]);
    const SE3 c_inv_b = c.inverse() * b;
    const auto M = [&](std::size_t k) -> Matrix6d {
      switch (k) {
        case 0:
          return c_inv_b.adjoint();
        case 1:  // both of x_{t-1}'s inverses
          return -(c_inv_b * a.inverse() * b).adjoint() - c_inv_b.adjoint();
        default:
          return Matrix6d::Identity();
      }
    };
    const SE3 E = b.inverse() * a * (b.inverse() * c);
    return detail::log_error<3>(E, sqrt_info_, x, r, jacobians, M);
  }
  static ceres::CostFunction* create(const Matrix6d& sqrt_info,
                                     const std::array<SE3, 3>& T_frame_world = {}) {
    return new ConstantVelocityFactor(sqrt_info, T_frame_world);
  }

 private:
  Matrix6d sqrt_info_;
  std::array<SE3, 3> T_frame_world_;  // F^-1 of each pose, oldest first
};

// Not in the paper: a weak zero-velocity prior, r = S log(x_{t-1}^-1 x_t). Along directions no
// measurement sees (an edge's axis, a sphere's rotation) the velocity prior alone would let any
// velocity that once entered continue for ever; this one lets it decay instead.
class VelocityDampingFactor final : public ceres::SizedCostFunction<6, 7, 7> {
 public:
  VelocityDampingFactor(const Matrix6d& sqrt_info, const std::array<SE3, 2>& T_frame_world)
      : sqrt_info_(sqrt_info), T_frame_world_(T_frame_world) {}
  bool Evaluate(double const* const* x, double* r, double** jacobians) const override {
    const SE3 a = T_frame_world_[0] * pose_from_block(x[0]);
    const SE3 b_inv_a = (T_frame_world_[1] * pose_from_block(x[1])).inverse() * a;
    const auto M = [&](std::size_t k) -> Matrix6d {
      if (k == 0) return -b_inv_a.adjoint();
      return Matrix6d::Identity();
    };
    return detail::log_error<2>(b_inv_a.inverse(), sqrt_info_, x, r, jacobians, M);
  }
  static ceres::CostFunction* create(const Matrix6d& sqrt_info,
                                     const std::array<SE3, 2>& T_frame_world = {}) {
    return new VelocityDampingFactor(sqrt_info, T_frame_world);
  }

 private:
  Matrix6d sqrt_info_;
  std::array<SE3, 2> T_frame_world_;
};

// Eq. 8 (end-effector prior on e_t) and eq. 9 (vision prior on the first o_t of an episode):
// r = S log(T_meas^-1 x).
class PosePriorFactor final : public ceres::SizedCostFunction<6, 7> {
 public:
  PosePriorFactor(const SE3& T_meas, const Matrix6d& sqrt_info)
      : T_meas_inv_(T_meas.inverse()), sqrt_info_(sqrt_info) {}
  bool Evaluate(double const* const* x, double* r, double** jacobians) const override {
    const auto M = [](std::size_t) -> Matrix6d { return Matrix6d::Identity(); };
    return detail::log_error<1>(T_meas_inv_ * pose_from_block(x[0]), sqrt_info_, x, r, jacobians,
                                M);
  }
  static ceres::CostFunction* create(const SE3& T_meas, const Matrix6d& sqrt_info) {
    return new PosePriorFactor(T_meas, sqrt_info);
  }

 private:
  SE3 T_meas_inv_;
  Matrix6d sqrt_info_;
};

// S for an isotropic sigma on all six axes ([m] and [rad] alike, as in the paper).
inline Matrix6d isotropic_sqrt_info(double sigma) { return Matrix6d::Identity() / sigma; }

// S with S^T S = information, for a symmetric positive semi-definite information matrix
// (directions with zero information get zero rows).
Matrix6d sqrt_information(const Matrix6d& information);

}  // namespace pg
