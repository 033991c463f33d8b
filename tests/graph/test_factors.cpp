// The factor graph's building blocks: the SE(3) manifold, and each factor's residual (zero at
// the truth) and Jacobian (against numeric differentiation on the manifold).
#include <ceres/manifold_test_utils.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

#include "pg/graph/factors.h"

namespace pg {
namespace {

SE3 random_pose(std::mt19937& rng, double t_scale = 0.02, double r_scale = 1.0) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Vector6d xi;
  for (int k = 0; k < 3; ++k) xi[k] = t_scale * u(rng);
  for (int k = 3; k < 6; ++k) xi[k] = r_scale * u(rng);
  return SE3::exp(xi);
}

struct Block {
  double v[kPoseBlockSize];
  explicit Block(const SE3& p) { pose_to_block(p, v); }
};

TEST(SE3Manifold, PassesCeresManifoldInvariants) {
  using namespace ceres;  // the invariants macro names ceres types unqualified
  const SE3Manifold manifold;
  std::mt19937 rng(3);
  for (int i = 0; i < 20; ++i) {
    const Block x(random_pose(rng));
    const Vector delta = 0.1 * Vector6d::Random();
    const Block y(pose_from_block(x.v) * SE3::exp(0.2 * Vector6d::Random()));
    Vector xv(kPoseBlockSize), yv(kPoseBlockSize);
    for (int k = 0; k < kPoseBlockSize; ++k) xv[k] = x.v[k], yv[k] = y.v[k];
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, xv, delta, yv, 1e-9);
  }
}

// The written-out PlusJacobian against the automatic one of the same Plus, at random poses and
// at a block whose quaternion is not of unit length (Plus normalises it).
TEST(SE3Manifold, PlusJacobianEqualsTheAutomaticOne) {
  const SE3Manifold manifold;
  const ceres::AutoDiffManifold<SE3RightPlus, kPoseBlockSize, kPoseTangentSize> automatic;
  std::mt19937 rng(5);
  for (int i = 0; i < 21; ++i) {
    Block x(random_pose(rng));
    if (i == 20) {
      for (int k = 3; k < 7; ++k) x.v[k] *= 3.0;
    }
    Eigen::Matrix<double, 7, 6, Eigen::RowMajor> written, automatic_jacobian;
    ASSERT_TRUE(manifold.PlusJacobian(x.v, written.data()));
    ASSERT_TRUE(automatic.PlusJacobian(x.v, automatic_jacobian.data()));
    EXPECT_LT((written - automatic_jacobian).cwiseAbs().maxCoeff(), 1e-14) << "pose " << i << "\n"
                                                                           << written << "\n---\n"
                                                                           << automatic_jacobian;
  }
}

std::vector<double> evaluate(const ceres::CostFunction& cost, const std::vector<double*>& blocks,
                             std::vector<std::vector<double>>* jacobians = nullptr) {
  std::vector<double> r(cost.num_residuals());
  std::vector<double*> jac_ptrs;
  if (jacobians) {
    jacobians->assign(blocks.size(), std::vector<double>(r.size() * kPoseBlockSize));
    for (auto& j : *jacobians) jac_ptrs.push_back(j.data());
  }
  EXPECT_TRUE(cost.Evaluate(blocks.data(), r.data(), jacobians ? jac_ptrs.data() : nullptr));
  return r;
}

// Residual zero at the truth; away from it, the autodiff Jacobian through the manifold's
// PlusJacobian equals central differences of r(x [+] h e_k) in the tangent space.
void check_factor(ceres::CostFunction* cost, const std::vector<double*>& truth) {
  std::unique_ptr<ceres::CostFunction> owned(cost);
  for (double r : evaluate(*cost, truth)) EXPECT_NEAR(r, 0.0, 1e-7);
  std::mt19937 rng(11);
  std::vector<std::vector<double>> moved;
  std::vector<double*> blocks;
  for (double* b : truth) {
    const Block m(pose_from_block(b) * random_pose(rng, 0.001, 0.05));
    moved.emplace_back(m.v, m.v + kPoseBlockSize);
  }
  for (auto& m : moved) blocks.push_back(m.data());
  std::vector<std::vector<double>> ambient;
  evaluate(*cost, blocks, &ambient);
  const SE3Manifold manifold;
  const int n = cost->num_residuals();
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    Eigen::Matrix<double, 7, 6, Eigen::RowMajor> plus;
    ASSERT_TRUE(manifold.PlusJacobian(blocks[b], plus.data()));
    const Eigen::MatrixXd J = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 7, Eigen::RowMajor>>(
                                  ambient[b].data(), n, 7) * plus;
    Eigen::MatrixXd J_num(n, 6);
    const double h = 1e-7;
    for (int k = 0; k < 6; ++k) {
      std::vector<double> r_plus, r_minus;
      for (double sign : {1.0, -1.0}) {
        const Vector6d delta = sign * h * Vector6d::Unit(k);
        double x[kPoseBlockSize];
        manifold.Plus(moved[b].data(), delta.data(), x);
        std::vector<double*> probe = blocks;
        probe[b] = x;
        (sign > 0 ? r_plus : r_minus) = evaluate(*cost, probe);
      }
      for (int i = 0; i < n; ++i) J_num(i, k) = (r_plus[i] - r_minus[i]) / (2 * h);
    }
    EXPECT_LT((J - J_num).norm(), 1e-5 * std::max(1.0, J.norm())) << "block " << b << "\n"
                                                                   << J << "\n---\n" << J_num;
  }
}

TEST(Factors, ZeroAtTheTruthWithJacobiansMatchingNumericOnes) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    const SE3 o0 = random_pose(rng), e0 = random_pose(rng);
    // Constant velocity: o2 = o1 (o0^-1 o1).
    const SE3 step = random_pose(rng, 0.002, 0.05);
    const SE3 o1 = o0 * step, o2 = o1 * step, e1 = e0 * random_pose(rng, 0.002, 0.05);
    Block bo0(o0), bo1(o1), bo2(o2), be0(e0), be1(e1);
    const Matrix6d S = isotropic_sqrt_info(1e-3);
    // Eq. 5: points of the object in S_cur moved into S_prev.
    const SE3 T_prev_cur = (e0.inverse() * o0) * (e1.inverse() * o1).inverse();
    check_factor(ImageToImageFactor::create(T_prev_cur, S), {bo0.v, be0.v, bo1.v, be1.v});
    // Eq. 6: the patch registration measures T_object_sensor.
    check_factor(ImageToPatchFactor::create(o1.inverse() * e1, S), {bo1.v, be1.v});
    // Eq. 7, and the damping prior (o0 = o0: no motion).
    check_factor(ConstantVelocityFactor::create(S), {bo0.v, bo1.v, bo2.v});
    check_factor(VelocityDampingFactor::create(S), {bo0.v, bo0.v});
    // Both in the frame of a moving sensor E_t: x_t = E_t^-1 o_t moves at constant velocity, and
    // stands still for the damping prior, while o_t itself does neither.
    const SE3 E0 = random_pose(rng), E1 = random_pose(rng), E2 = random_pose(rng);
    const SE3 x0 = random_pose(rng), x1 = x0 * step, x2 = x1 * step;
    Block held0(E0 * x0), held1(E1 * x1), held2(E2 * x2), still1(E1 * x0);
    check_factor(ConstantVelocityFactor::create(S, {E0.inverse(), E1.inverse(), E2.inverse()}),
                 {held0.v, held1.v, held2.v});
    check_factor(VelocityDampingFactor::create(S, {E0.inverse(), E1.inverse()}),
                 {held0.v, still1.v});
    std::unique_ptr<ceres::CostFunction> world(ConstantVelocityFactor::create(S));
    const std::vector<double*> held = {held0.v, held1.v, held2.v};
    double moved = 0;
    for (double r : evaluate(*world, held)) moved = std::max(moved, std::abs(r));
    EXPECT_GT(moved, 1.0) << "the sensor's motion is not a constant velocity in the world";
    // Eq. 8 and 9.
    check_factor(PosePriorFactor::create(e1, S), {be1.v});
  }
}

TEST(Factors, SqrtInformationSquaresBackAndKeepsNullDirections) {
  Matrix6d A = Matrix6d::Random();
  Matrix6d info = A * A.transpose();
  info.row(5).setZero();
  info.col(5).setZero();
  const Matrix6d S = sqrt_information(info);
  EXPECT_LT((S.transpose() * S - info).norm(), 1e-9 * info.norm());
  EXPECT_LT((S * Vector6d::Unit(5)).norm(), 1e-9);
}

}  // namespace
}  // namespace pg
