#include "pg/tracker/degeneracy.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>

namespace pg {

namespace {

// In choosing among equally good steps, one radian of rotation costs as much as this much
// translation: large, so the step removes rotation first.
constexpr double kRotationCostLengthM = 1.0;

// A rotation an unconstrained direction holds is a sliver (DegeneracyReport::unconstrained_twists)
// when taking it out raises the direction's cost by at most this fraction of the threshold.
// Measured: the benchmark cube edges' slide at most 0.01 of it (up to 0.03 on the stress suite's
// edges and flat faces), the roll of a sphere's nearly flat cap (a rotation about its far centre)
// 0.34 at 30 mm radius, 0.22 at 25 mm pressed less, 0.027 at 0.15 m, 0.006 at 0.3-1 m: no cost
// tells a large sphere's roll from an edge's sliver, so a roll is recognised by the contact's
// curvature instead (free_twists). The ICP step's cost is the stricter: the least-rotation step
// needs the roll to undo the tilt the constrained step carries when a cap translates.
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

// The projector onto the rotations (columns, scaled [Lambda phi]) of a span of free directions
// that are no slivers. The eigenvectors of a cluster of small eigenvalues are fixed by the data
// only up to mixing with their neighbours: an edge's slide (eigenvalue 0.01) comes out with a
// little of the turn about the edge or about the contact's normal. A rotation direction u the
// span holds with singular value s is such a sliver when the rotation itself is constrained (its
// curvature u^T H_rr u above the threshold) yet taking it out of a unit direction adds only about
// s^2 u^T H_rr u, at most sliver_cost x the threshold. A flat patch's spin (a free rotation) is
// kept. A sliver_cost of kAllConstrained keeps only the free rotations.
constexpr double kAllConstrained = std::numeric_limits<double>::infinity();
Eigen::Matrix3d non_sliver_rotations(const Eigen::Matrix3Xd& rotations, const Eigen::Matrix3d& H_rr,
                                     double threshold, double sliver_cost) {
  const Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(rotations, Eigen::ComputeFullU);
  Eigen::Matrix3d resolved = Eigen::Matrix3d::Zero();
  for (int j = 0; j < int(svd.singularValues().size()); ++j) {
    const Eigen::Vector3d u = svd.matrixU().col(j);
    const double s = svd.singularValues()[j];
    const double curvature = u.dot(H_rr * u);
    const bool sliver = curvature > threshold && s * s * curvature <= sliver_cost * threshold;
    if (s > 0.0 && !sliver) resolved += u * u.transpose();
  }
  return resolved;
}

// A free direction's rotation is taken for a roll about the contact's centre of curvature when
// the roll leaves at most this fraction of its constrained part unexplained and the directions
// with the roll cost at most kRollCostGain of what they cost with the sliver removed. Measured
// (DegeneracyReport's comment): spheres of 6 mm to 1 m leave 0.0002-0.056 unexplained at cost
// ratios 0.07-0.11; the benchmark's cube edges and toy human 0.011 and up, but mostly 0.2-1,
// at cost ratios mostly 0.3-1, and no frame of cube 01, 05, 19 or toy human 03, 15 passes both.
constexpr double kRollUnexplained = 0.1;
constexpr double kRollCostGain = 0.5;
constexpr double kMinMeanNormal = 0.3;

// How far the columns (scaled directions) are from free: their mean Rayleigh quotient.
double mean_cost(const Matrix6d& H, const Matrix6Xd& X) {
  double cost = 0;
  for (int i = 0; i < int(X.cols()); ++i) {
    const double norm_sq = X.col(i).squaredNorm();
    if (norm_sq > 0) cost += X.col(i).dot(H * X.col(i)) / norm_sq;
  }
  return X.cols() > 0 ? cost / double(X.cols()) : 0.0;
}

// The rotation (scaled, Lambda phi) that rolling the contact about its centre of curvature
// carries with each free direction's slide rho (scaled = unscaled): phi = kappa n x rho_t, with
// rho_t the slide's part along the surface and kappa = rho_t^T K rho_t / |rho_t|^2 the normal
// curvature along it. A sphere's roll about its centre: phi = n x rho / R. Not K rho itself: a
// slide along an edge with a little of a slide across it would borrow the rounding's curvature
// (1 / 1 mm) for a roll that is not there.
Eigen::Matrix3Xd rolling_rotations(const DegeneracyReport& report, const Matrix6Xd& free) {
  const Eigen::Vector3d n = report.shape.mean_normal.normalized();
  Eigen::Matrix3Xd predicted(3, free.cols());
  for (int i = 0; i < int(free.cols()); ++i) {
    const Eigen::Vector3d rho = free.col(i).head<3>();
    const Eigen::Vector3d slide = rho - n * n.dot(rho);
    const double length_sq = slide.squaredNorm();
    const double curvature =
        length_sq > 0 ? slide.dot(report.shape.shape_operator * slide) / length_sq : 0.0;
    predicted.col(i) = report.rotation_scale_m * (curvature * n.cross(slide));
  }
  return predicted;
}

// Three free twists N (about c) of a nearly flat contact become a flat face's: their tilt goes
// when, over the span, it is less than the slide along the contact over report.flat_radius_m
// (the rolls of a farther centre). Measured on the two-sensor regrasp's cube faces through the
// default model: 1.2-21 rad of tilt per metre of slide (median 8), about 1e-4 from the rendered
// normals; a 6 mm ball's rolls 167. Kept as they are when the tilt-free twists would no longer
// span three directions.
void drop_flat_tilt(const DegeneracyReport& report, Matrix6Xd& N) {
  if (report.shape.mean_normal.norm() < kMinMeanNormal) return;
  const Eigen::Vector3d n = report.shape.mean_normal.normalized();
  const Eigen::Matrix3d across = Eigen::Matrix3d::Identity() - n * n.transpose();
  const double tilt = (across * N.bottomRows<3>()).norm();
  const double slide = (across * N.topRows<3>()).norm();
  if (!(tilt * report.flat_radius_m < slide)) return;
  Matrix6Xd flat = N;
  flat.bottomRows<3>() = n * (n.transpose() * N.bottomRows<3>());
  const Eigen::JacobiSVD<Matrix6Xd> svd(flat);
  const auto& s = svd.singularValues();
  if (s[s.size() - 1] > 1e-6 * s[0]) N = flat;
}

// DegeneracyReport::unconstrained_twists with the given sliver cost.
Matrix6Xd free_twists(const DegeneracyReport& report, double sliver_cost) {
  const int k = report.unconstrained;
  Matrix6Xd N(6, k);
  if (k == 0) return N;
  const double threshold = report.min_eigenvalue_ratio * report.eigenvalues[5];
  const Matrix6d H =
      report.eigenvectors * report.eigenvalues.asDiagonal() * report.eigenvectors.transpose();
  const Eigen::Matrix3d H_rr = H.bottomRightCorner<3, 3>();
  const Matrix6Xd free = report.eigenvectors.leftCols(k);
  const Eigen::Matrix3Xd rotations = free.bottomRows<3>();
  Matrix6Xd chosen = free;  // scaled coordinates
  chosen.bottomRows<3>() =
      non_sliver_rotations(rotations, H_rr, threshold, sliver_cost) * rotations;
  // A roll is no sliver: set aside the rotation rolling predicts, remove slivers from the rest.
  // Only for a contact whose normals face one side (a tactile contact's do; a mean normal
  // shorter than kMinMeanNormal has no direction to roll about).
  if (report.shape.mean_normal.norm() >= kMinMeanNormal && !report.shape.shape_operator.isZero(0)) {
    const Eigen::Matrix3Xd predicted = rolling_rotations(report, free);
    const Eigen::Matrix3Xd residual = rotations - predicted;
    const auto constrained_part = [&](const Eigen::Matrix3Xd& r) {
      return (r - non_sliver_rotations(r, H_rr, threshold, kAllConstrained) * r).norm();
    };
    Matrix6Xd rolling = free;
    rolling.bottomRows<3>() =
        predicted + non_sliver_rotations(residual, H_rr, threshold, sliver_cost) * residual;
    if (constrained_part(residual) <= kRollUnexplained * constrained_part(rotations) &&
        mean_cost(H, rolling) < kRollCostGain * mean_cost(H, chosen)) {
      chosen = rolling;
    }
  }
  for (int i = 0; i < k; ++i) N.col(i) = unscale(chosen.col(i), report.rotation_scale_m);
  if (k == 3 && report.flat_radius_m > 0) drop_flat_tilt(report, N);
  return N;
}

}  // namespace

ContactShape fit_contact_shape(const std::vector<Eigen::Vector3f>& points,
                               const std::vector<Eigen::Vector3f>& normals) {
  ContactShape shape;
  const std::size_t n = std::min(points.size(), normals.size());
  if (n < 4) return shape;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    centre += points[i].cast<double>();
    shape.mean_normal += normals[i].cast<double>();
  }
  centre /= double(n);
  shape.mean_normal /= double(n);
  // K = B A^+ with A = sum r r^T, B = sum (n - mean n) r^T: the least-squares fit of
  // n = mean n + K r. A plane's A is singular along its normal, where its B is zero.
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero(), B = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d r = points[i].cast<double>() - centre;
    A += r * r.transpose();
    B += (normals[i].cast<double>() - shape.mean_normal) * r.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(A);
  const double largest = eig.eigenvalues()[2];
  if (!(largest > 0)) return shape;
  Eigen::Vector3d inverse = Eigen::Vector3d::Zero();
  for (int k = 0; k < 3; ++k) {
    if (eig.eigenvalues()[k] > 1e-9 * largest) inverse[k] = 1.0 / eig.eigenvalues()[k];
  }
  const Eigen::Matrix3d K =
      B * eig.eigenvectors() * inverse.asDiagonal() * eig.eigenvectors().transpose();
  shape.shape_operator = 0.5 * (K + K.transpose());
  if (!shape.shape_operator.allFinite() || !shape.mean_normal.allFinite()) return ContactShape();
  return shape;
}

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
                                    double min_eigenvalue_ratio, const ContactShape& shape,
                                    double flat_radius_m) {
  DegeneracyReport report;
  report.centre_target = centre_target;
  report.rotation_scale_m = rotation_scale_m;
  report.shape = shape;
  report.flat_radius_m = flat_radius_m;
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
  return analyse_degeneracy(BM * H0 * BM.transpose(), c, Lambda, min_eigenvalue_ratio,
                            fit_contact_shape(cloud.points, cloud.normals));
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
