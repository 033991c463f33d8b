#include "pg/tracker/degeneracy.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace pg {

namespace {

// In choosing among equally good steps, one radian of rotation costs as much as this much
// translation: large, so the step removes rotation first.
constexpr double kRotationCostLengthM = 1.0;

// A rotation an unconstrained direction holds is a sliver (DegeneracyReport::unconstrained_twists)
// when taking it out raises the direction's cost by at most this fraction of the threshold.
// Measured: the benchmark cube edges' slide at most 0.01 of it, the roll of a 50 mm sphere's
// nearly flat cap (a rotation about its far centre) 0.22. The free directions handed to the
// factor graph drop the cap's roll too (then a slide); the ICP step keeps it, because the
// least-rotation step needs it to undo the tilt the constrained step carries when the cap
// translates (without it that cap's registrations tilted and lost the patch).
constexpr double kSliverCost = 0.25;
constexpr double kStepSliverCost = 0.05;

// Scaled coordinates [rho_c; Lambda phi] -> twist [rho_c; phi].
Vector6d unscale(const Vector6d& x, const Eigen::Matrix3d& Lambda) {
  Vector6d d = x;
  d.tail<3>() = Lambda.ldlt().solve(x.tail<3>());
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
        const double t =
            (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
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

// DegeneracyReport::unconstrained_twists with the given sliver cost.
Matrix6Xd free_twists(const DegeneracyReport& report, double sliver_cost) {
  const int k = report.unconstrained;
  const Vector6d& eigenvalues = report.eigenvalues;
  const Matrix6d& eigenvectors = report.eigenvectors;
  Matrix6Xd N(6, k);
  if (k == 0) return N;
  // The eigenvectors of a cluster of small eigenvalues are fixed by the data only up to mixing
  // with their neighbours: an edge's slide (eigenvalue 0.01) comes out with a little of the turn
  // about the edge or about the contact's normal. A rotation direction u the span holds with
  // singular value s is such a sliver when the rotation itself is constrained (its curvature
  // u^T H_rr u above the threshold) yet taking it out of a unit direction adds only about
  // s^2 u^T H_rr u, at most sliver_cost x the threshold. A sphere's roll (a stiff tilt about c
  // carried by a translation, s about Lambda / R) keeps its rotation, a flat patch's spin (a free
  // rotation) too.
  const double threshold = report.min_eigenvalue_ratio * eigenvalues[5];
  const Matrix6d H = eigenvectors * eigenvalues.asDiagonal() * eigenvectors.transpose();
  const Eigen::Matrix3d H_rr = H.bottomRightCorner<3, 3>();
  const Eigen::Matrix3Xd rotations = eigenvectors.block(3, 0, 3, k);
  const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(rotations, Eigen::ComputeFullU);
  Eigen::Matrix3d resolved = Eigen::Matrix3d::Zero();  // projector onto the rotations kept
  for (int j = 0; j < int(svd.singularValues().size()); ++j) {
    const Eigen::Vector3d u = svd.matrixU().col(j);
    const double s = svd.singularValues()[j];
    const double curvature = u.dot(H_rr * u);
    const bool sliver = curvature > threshold && s * s * curvature <= sliver_cost * threshold;
    if (s > 0.0 && !sliver) resolved += u * u.transpose();
  }
  for (int i = 0; i < k; ++i) {
    Vector6d x = eigenvectors.col(i);
    x.tail<3>() = resolved * x.tail<3>();
    N.col(i) = unscale(x, report.rotation_scale_m);
  }
  return N;
}

}  // namespace

Eigen::Matrix3d rotation_scale(const Eigen::Matrix3d& mean_outer_product_about_c) {
  const Eigen::Matrix3d& S = mean_outer_product_about_c;
  const Eigen::Matrix3d J = S.trace() * Eigen::Matrix3d::Identity() - S;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(J);
  const double largest = std::sqrt(std::max(eig.eigenvalues()[2], 0.0));
  const double floor = std::max(1e-3 * largest, 1e-9);
  Eigen::Vector3d extent;
  for (int k = 0; k < 3; ++k)
    extent[k] = std::max(std::sqrt(std::max(eig.eigenvalues()[k], 0.0)), floor);
  return eig.eigenvectors() * extent.asDiagonal() * eig.eigenvectors().transpose();
}

DegeneracyReport analyse_degeneracy(const Matrix6d& H_scaled, const Eigen::Vector3d& centre_target,
                                    const Eigen::Matrix3d& rotation_scale_m,
                                    double min_eigenvalue_ratio) {
  DegeneracyReport report;
  report.centre_target = centre_target;
  report.rotation_scale_m = rotation_scale_m;
  symmetric_eigen(H_scaled, report.eigenvalues, report.eigenvectors);
  const double largest = report.eigenvalues[5];
  // Never below the eigen-solver's rounding: a ratio of 0 took a flat patch's rounding-level
  // eigenvalues (1e-18 of the largest) for constrained directions and stepped by their inverse.
  constexpr double kRoundingRatio = 1e-12;
  report.min_eigenvalue_ratio = std::max(min_eigenvalue_ratio, kRoundingRatio);
  report.unconstrained = 0;
  for (int i = 0; i < 6; ++i) {
    if (largest <= 0.0 || report.eigenvalues[i] <= report.min_eigenvalue_ratio * largest) {
      report.unconstrained = i + 1;
    }
  }
  return report;
}

DegeneracyReport analyse_cloud_degeneracy(const PointCloud& cloud, double min_eigenvalue_ratio) {
  const std::size_t n = std::min(cloud.points.size(), cloud.normals.size());
  if (n == 0) return DegeneracyReport();  // 6 unconstrained
  // One pass about the first point p0 (r = p - p0, small, so no cancellation): the sums of r and
  // r r^T, and the Hessian H0 of J0 = [n; r x n]. About the centroid c = p0 + m the Jacobian is
  // J = [n; (r - m) x n] = M J0 with M = [I 0; -[m]x I], and scaled [n; Lambda^-1 (r - m) x n] =
  // B M J0 with B = diag(I, Lambda^-1). Plain scalars: this runs on every contact frame, twice.
  const Eigen::Vector3f p0 = cloud.points[0];
  double s[3] = {}, ss[6] = {}, h[21] = {};
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3f& p = cloud.points[i];
    const Eigen::Vector3f& nf = cloud.normals[i];
    const double rx = p.x() - p0.x(), ry = p.y() - p0.y(), rz = p.z() - p0.z();
    const double nx = nf.x(), ny = nf.y(), nz = nf.z();
    const double j[6] = {nx, ny, nz, ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx};
    s[0] += rx;
    s[1] += ry;
    s[2] += rz;
    ss[0] += rx * rx;
    ss[1] += rx * ry;
    ss[2] += rx * rz;
    ss[3] += ry * ry;
    ss[4] += ry * rz;
    ss[5] += rz * rz;
    for (int a = 0, k = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b, ++k) h[k] += j[a] * j[b];
    }
  }
  const Eigen::Vector3d m = Eigen::Vector3d(s[0], s[1], s[2]) / double(n);
  Eigen::Matrix3d second;  // mean of r r^T
  second << ss[0], ss[1], ss[2], ss[1], ss[3], ss[4], ss[2], ss[4], ss[5];
  const Eigen::Matrix3d Lambda = rotation_scale(second / double(n) - m * m.transpose());
  Matrix6d H0;
  for (int a = 0, k = 0; a < 6; ++a) {
    for (int b = a; b < 6; ++b, ++k) H0(a, b) = H0(b, a) = h[k];
  }
  Matrix6d BM = Matrix6d::Identity();
  const Eigen::Matrix3d Lambda_inv = Lambda.inverse();
  BM.bottomLeftCorner<3, 3>() = -Lambda_inv * hat<double>(m);
  BM.bottomRightCorner<3, 3>() = Lambda_inv;
  const Eigen::Vector3d c = p0.cast<double>() + m;
  return analyse_degeneracy(BM * H0 * BM.transpose(), c, Lambda, min_eigenvalue_ratio);
}

Matrix6Xd DegeneracyReport::unconstrained_twists() const { return free_twists(*this, kSliverCost); }

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
  Vector6d step = unscale(x, report.rotation_scale_m);
  if (report.unconstrained == 0 || report.unconstrained == 6) return step;
  // Project out the unconstrained directions in the metric M = diag(1, 1, 1, l^2, l^2, l^2):
  // step <- step - sum_i b_i (b_i^T M step), with b_i an M-orthonormal basis of their span
  // (Gram-Schmidt; fixed-size vectors, no allocation).
  Vector6d m;
  m << 1, 1, 1, Eigen::Vector3d::Constant(kRotationCostLengthM * kRotationCostLengthM);
  const Matrix6Xd free = free_twists(report, kStepSliverCost);
  Vector6d basis[6];
  int k = 0;
  for (int i = 0; i < int(free.cols()); ++i) {
    Vector6d b = free.col(i);
    for (int j = 0; j < k; ++j) b -= basis[j] * basis[j].dot(m.cwiseProduct(b));
    const double norm = std::sqrt(b.dot(m.cwiseProduct(b)));
    if (norm > 1e-12) basis[k++] = b / norm;
  }
  for (int j = 0; j < k; ++j) step -= basis[j] * basis[j].dot(m.cwiseProduct(step));
  return step;
}

int common_unconstrained_directions(const std::vector<Matrix6Xd>& twists) {
  if (twists.empty()) return 6;
  const Vector6d weights = (Vector6d() << 1, 1, 1, 1e-2, 1e-2, 1e-2).finished();
  Eigen::MatrixXd common = weights.asDiagonal() * twists[0];
  for (std::size_t k = 1; k < twists.size() && common.cols() > 0; ++k) {
    if (twists[k].cols() == 0) return 0;
    // Orthonormal bases of both spans; their common directions are the principal angles of 0,
    // singular values of Q1^T Q2 of 1.
    const Eigen::MatrixXd q1 = Eigen::HouseholderQR<Eigen::MatrixXd>(common).householderQ() *
                               Eigen::MatrixXd::Identity(6, common.cols());
    const Eigen::MatrixXd next = weights.asDiagonal() * twists[k];
    const Eigen::MatrixXd q2 = Eigen::HouseholderQR<Eigen::MatrixXd>(next).householderQ() *
                               Eigen::MatrixXd::Identity(6, next.cols());
    const Eigen::JacobiSVD<Eigen::MatrixXd> svd(q1.transpose() * q2, Eigen::ComputeThinU);
    int shared = 0;
    // Within about 3 degrees of each other.
    while (shared < svd.singularValues().size() && svd.singularValues()[shared] > 0.9986) {
      ++shared;
    }
    common = q1 * svd.matrixU().leftCols(shared);
  }
  return int(common.cols());
}

}  // namespace pg
