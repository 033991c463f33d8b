#include "pg/graph/factors.h"

#include <Eigen/Eigenvalues>

namespace pg {

Matrix6d sqrt_information(const Matrix6d& information) {
  const Eigen::SelfAdjointEigenSolver<Matrix6d> eig(0.5 * (information + information.transpose()));
  const Vector6d root = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  return root.asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace pg
