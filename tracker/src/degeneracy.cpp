#include "pg/tracker/degeneracy.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace pg {

namespace {

// In choosing among equally good steps, one radian of rotation costs as much as this much
// translation: large, so the step removes rotation first.
constexpr double kRotationCostLengthM = 1.0;

// Unconstrained twists drop rotation directions their span holds with a scaled singular value
// below this times sqrt(min_eigenvalue_ratio) (see DegeneracyReport::unconstrained_twists).
constexpr double kUnresolvedRotation = 0.5;

// Scaled coordinates [rho_c; L phi] -> twist [rho_c; phi].
Vector6d unscale(const Vector6d& x, double L) {
  Vector6d d = x;
  d.tail<3>() /= L;
  return d;
}

// Cyclic Jacobi eigen-decomposition of a symmetric 6x6 matrix (accurate to machine precision for
// the tiny eigenvalues that matter here), eigenvalues ascending with their vectors as columns.
void symmetric_eigen(const Matrix6d& H, Vector6d& values, Matrix6d& vectors) {
  Matrix6d A = 0.5 * (H + H.transpose());
  Matrix6d V = Matrix6d::Identity();
  for (int sweep = 0; sweep < 50; ++sweep) {
    double off = 0.0;
    for (int p = 0; p < 6; ++p) {
      for (int q = p + 1; q < 6; ++q) off += A(p, q) * A(p, q);
    }
    if (off <= 1e-30 * A.squaredNorm() || off == 0.0) break;
    for (int p = 0; p < 6; ++p) {
      for (int q = p + 1; q < 6; ++q) {
        if (A(p, q) == 0.0) continue;
        // The rotation in the (p, q) plane that zeroes A(p, q).
        const double theta = (A(q, q) - A(p, p)) / (2.0 * A(p, q));
        const double t = (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
        const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
        for (int k = 0; k < 6; ++k) {  // A <- A G
          const double akp = A(k, p), akq = A(k, q);
          A(k, p) = c * akp - s * akq;
          A(k, q) = s * akp + c * akq;
        }
        for (int k = 0; k < 6; ++k) {  // A <- G^T A
          const double apk = A(p, k), aqk = A(q, k);
          A(p, k) = c * apk - s * aqk;
          A(q, k) = s * apk + c * aqk;
        }
        for (int k = 0; k < 6; ++k) {  // V <- V G
          const double vkp = V(k, p), vkq = V(k, q);
          V(k, p) = c * vkp - s * vkq;
          V(k, q) = s * vkp + c * vkq;
        }
      }
    }
  }
  int order[6] = {0, 1, 2, 3, 4, 5};
  std::sort(order, order + 6, [&](int a, int b) { return A(a, a) < A(b, b); });
  for (int i = 0; i < 6; ++i) {
    values[i] = A(order[i], order[i]);
    vectors.col(i) = V.col(order[i]);
  }
}

}  // namespace

DegeneracyReport analyse_degeneracy(const Matrix6d& H_scaled, const Eigen::Vector3d& centre_target,
                                    double length_scale_m, double min_eigenvalue_ratio) {
  DegeneracyReport report;
  report.centre_target = centre_target;
  report.length_scale_m = length_scale_m;
  symmetric_eigen(H_scaled, report.eigenvalues, report.eigenvectors);
  const double largest = report.eigenvalues[5];
  report.min_eigenvalue_ratio = min_eigenvalue_ratio;
  report.unconstrained = 0;
  for (int i = 0; i < 6; ++i) {
    if (largest <= 0.0 || report.eigenvalues[i] <= min_eigenvalue_ratio * largest) {
      report.unconstrained = i + 1;
    }
  }
  return report;
}

Matrix6Xd DegeneracyReport::unconstrained_twists() const {
  const int k = unconstrained;
  Matrix6Xd N(6, k);
  if (k == 0) return N;
  // The eigenvectors of a cluster of small eigenvalues are fixed by the data only up to mixing
  // with the others: an edge's slide (eigenvalue 0.01) comes out with a 1e-3 rotation part that
  // changes its cost by 1e-4. Rotation directions the span holds with a singular value below tol
  // are such slivers: taking them out of a unit direction adds at most about
  // lambda_max tol^2 = lambda_max ratio / 4 to its cost, so it stays unconstrained.
  const double tol = kUnresolvedRotation * std::sqrt(min_eigenvalue_ratio);
  const Eigen::Matrix3Xd rotations = eigenvectors.block(3, 0, 3, k);
  const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(rotations, Eigen::ComputeFullU);
  Eigen::Matrix3d resolved = Eigen::Matrix3d::Zero();  // projector onto the rotations kept
  for (int j = 0; j < int(svd.singularValues().size()); ++j) {
    if (svd.singularValues()[j] > tol) {
      resolved += svd.matrixU().col(j) * svd.matrixU().col(j).transpose();
    }
  }
  for (int i = 0; i < k; ++i) {
    Vector6d x = eigenvectors.col(i);
    x.tail<3>() = resolved * x.tail<3>();
    N.col(i) = unscale(x, length_scale_m);
  }
  return N;
}

Matrix6Xd DegeneracyReport::unconstrained_twists_at_origin() const {
  // exp(delta) = T_c exp(delta_c) T_c^-1  =>  delta = Ad(T_c) delta_c.
  const Matrix6d Ad = SE3::Translation(centre_target).adjoint();
  return Ad * unconstrained_twists();
}

Vector6d constrained_step(const DegeneracyReport& report, const Vector6d& g_scaled) {
  Vector6d x = Vector6d::Zero();
  for (int i = report.unconstrained; i < 6; ++i) {
    const auto v = report.eigenvectors.col(i);
    x -= v * (v.dot(g_scaled) / report.eigenvalues[i]);
  }
  Vector6d step = unscale(x, report.length_scale_m);
  if (report.unconstrained == 0 || report.unconstrained == 6) return step;
  // Project out the unconstrained directions in the metric M = diag(1, 1, 1, l^2, l^2, l^2):
  // step <- step - sum_i b_i (b_i^T M step), with b_i an M-orthonormal basis of their span
  // (Gram-Schmidt; fixed-size vectors, no allocation).
  Vector6d m;
  m << 1, 1, 1, Eigen::Vector3d::Constant(kRotationCostLengthM * kRotationCostLengthM);
  Vector6d basis[6];
  int k = 0;
  for (int i = 0; i < report.unconstrained; ++i) {
    Vector6d b = unscale(report.eigenvectors.col(i), report.length_scale_m);
    for (int j = 0; j < k; ++j) b -= basis[j] * basis[j].dot(m.cwiseProduct(b));
    const double norm = std::sqrt(b.dot(m.cwiseProduct(b)));
    if (norm > 1e-12) basis[k++] = b / norm;
  }
  for (int j = 0; j < k; ++j) step -= basis[j] * basis[j].dot(m.cwiseProduct(step));
  return step;
}

}  // namespace pg
