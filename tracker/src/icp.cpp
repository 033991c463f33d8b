#include "pg/tracker/icp.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <cmath>

#include "correspondence_cache.h"

namespace pg {

namespace {

// Points per parallel task: enough work to amortise the task overhead.
constexpr std::size_t kGrainSize = 256;

// The normal equations of one Gauss-Newton iteration (eq. 5/6 linearised), in scaled
// coordinates x = [rho_c; L phi] (degeneracy.h). Sums are kept in kLanes partial sums each: the
// terms of a chunk are added lane by lane, which compiles to vector FMAs with independent
// accumulators (a single running sum cannot be vectorised or reordered without -ffast-math, and
// its latency chain made the accumulation cost more than the rest of the linearisation).
constexpr int kLanes = 8;
struct NormalEquations {
  double H[21][kLanes] = {};        // upper triangle of sum w J J^T, row by row
  double g[6][kLanes] = {};         // sum w r J
  double weighted_sq[kLanes] = {};  // sum w r^2 [m^2]
  double weight[kLanes] = {};       // sum w
  double sq[kLanes] = {};           // sum r^2 over inliers [m^2]
  int inliers = 0;
  long queries = 0;

  // Adds m terms stored by column (J[a][i], w[i], r[i]); the columns m..(m rounded up to
  // kLanes) are overwritten with zero-weight terms.
  template <int kCapacity>
  void add_terms(double (&J)[6][kCapacity], double* w, double* r, int m) {
    static_assert(kCapacity % kLanes == 0);
    const int padded = (m + kLanes - 1) / kLanes * kLanes;
    for (int i = m; i < padded; ++i) {
      w[i] = r[i] = 0;
      for (int a = 0; a < 6; ++a) J[a][i] = 0;
    }
    for (int i0 = 0; i0 < padded; i0 += kLanes) {
      double wJ[6][kLanes];
      for (int a = 0; a < 6; ++a) {
        for (int l = 0; l < kLanes; ++l) wJ[a][l] = w[i0 + l] * J[a][i0 + l];
      }
      int k = 0;
      for (int a = 0; a < 6; ++a) {
        for (int l = 0; l < kLanes; ++l) g[a][l] += wJ[a][l] * r[i0 + l];
        for (int b = a; b < 6; ++b, ++k) {
          for (int l = 0; l < kLanes; ++l) H[k][l] += wJ[a][l] * J[b][i0 + l];
        }
      }
      for (int l = 0; l < kLanes; ++l) {
        const double wr = w[i0 + l] * r[i0 + l];
        weighted_sq[l] += wr * r[i0 + l];
        weight[l] += w[i0 + l];
        sq[l] += r[i0 + l] * r[i0 + l];
      }
    }
    inliers += m;
  }
  void add(const NormalEquations& o) {
    for (int l = 0; l < kLanes; ++l) {
      for (int k = 0; k < 21; ++k) H[k][l] += o.H[k][l];
      for (int a = 0; a < 6; ++a) g[a][l] += o.g[a][l];
      weighted_sq[l] += o.weighted_sq[l];
      weight[l] += o.weight[l];
      sq[l] += o.sq[l];
    }
    inliers += o.inliers;
    queries += o.queries;
  }
  static double total(const double (&lanes)[kLanes]) {
    double s = 0;
    for (double v : lanes) s += v;
    return s;
  }
  Matrix6d hessian() const {
    Matrix6d M;
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b) M(a, b) = M(b, a) = total(H[k++]);
    }
    return M;
  }
  Vector6d gradient() const {
    Vector6d v;
    for (int a = 0; a < 6; ++a) v[a] = total(g[a]);
    return v;
  }
};

struct Centroid {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  double rms_radius = 0;
};

Centroid centroid_and_radius(const std::vector<Eigen::Vector3f>& points) {
  Centroid c;
  for (const auto& p : points) c.centre += p.cast<double>();
  c.centre /= double(points.size());
  for (const auto& p : points) c.rms_radius += (p.cast<double>() - c.centre).squaredNorm();
  c.rms_radius = std::sqrt(c.rms_radius / double(points.size()));
  return c;
}

// Eq. 5/6 linearised at T: correspondences, robust weights and the normal equations in scaled
// coordinates about c, summed over every stride-th source point in parallel (oneTBB reduction).
NormalEquations linearise(const PointCloud& source, std::size_t stride,
                          const PointCloudTree& target, const SE3& T, const Eigen::Vector3d& c,
                          double inv_L, const IcpOptions& o, CorrespondenceCache& cache,
                          float radius) {
  const Eigen::Matrix3f R = T.rotation_matrix().cast<float>();
  const Eigen::Vector3f t = T.translation().cast<float>();
  const Eigen::Vector3f cf = c.cast<float>();
  const float max_corr = float(o.max_correspondence_m);
  const float max_corr_sq = max_corr * max_corr;
  const std::vector<Eigen::Vector3f>& src = source.points;
  const PointCloud& tgt = target.cloud();
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, (src.size() + stride - 1) / stride, kGrainSize),
      NormalEquations(),
      [&](const tbb::blocked_range<std::size_t>& range, NormalEquations acc) {
        constexpr int kChunk = 64;  // terms gathered before they are summed
        double J[6][kChunk], wc[kChunk], rc[kChunk];
        int m = 0;
        for (std::size_t k = range.begin(); k != range.end(); ++k) {
          const std::size_t i = k * stride;
          const Eigen::Vector3f p = R * src[i] + t;
          const int j = cache.nearest(i, p, target, radius, max_corr, acc.queries);
          if (j < 0) continue;
          const Eigen::Vector3f diff = p - tgt.points[j];
          if (diff.squaredNorm() > max_corr_sq) continue;
          const Eigen::Vector3f& n = tgt.normals[j];
          const double r = double(n.dot(diff));  // point-to-plane residual [m]
          const double w = robust_weight(o.kernel, o.kernel_scale_m, r);
          if (w <= 0.0) continue;
          // Jacobian about the centroid, rotation scaled by L: [n; ((p - c) x n) / L].
          const Eigen::Vector3f arm = (p - cf).cross(n);
          J[0][m] = n.x();
          J[1][m] = n.y();
          J[2][m] = n.z();
          J[3][m] = arm.x() * inv_L;
          J[4][m] = arm.y() * inv_L;
          J[5][m] = arm.z() * inv_L;
          wc[m] = w;
          rc[m] = r;
          if (++m == kChunk) {
            acc.add_terms(J, wc, rc, m);
            m = 0;
          }
        }
        acc.add_terms(J, wc, rc, m);
        return acc;
      },
      [](NormalEquations a, const NormalEquations& b) {
        a.add(b);
        return a;
      });
}

}  // namespace

const char* to_string(IcpStatus status) {
  switch (status) {
    case IcpStatus::kConverged:
      return "converged";
    case IcpStatus::kMaxIterations:
      return "max iterations";
    case IcpStatus::kTooFewPoints:
      return "too few points";
    case IcpStatus::kTooFewCorrespondences:
      return "too few correspondences";
  }
  return "?";
}

PointToPlaneIcp::PointToPlaneIcp(const IcpOptions& options)
    : options_(options), cache_(std::make_unique<CorrespondenceCache>()) {}
PointToPlaneIcp::~PointToPlaneIcp() = default;
PointToPlaneIcp::PointToPlaneIcp(PointToPlaneIcp&&) noexcept = default;
PointToPlaneIcp& PointToPlaneIcp::operator=(PointToPlaneIcp&&) noexcept = default;

IcpResult PointToPlaneIcp::align(const PointCloud& source_in, const PointCloudTree& target,
                                 const SE3& T_target_source_guess) {
  IcpResult result;
  result.T_target_source = T_target_source_guess;
  last_queries_ = 0;
  const IcpOptions& o = options_;
  const PointCloud* source = &source_in;
  if (o.voxel_size_m > 0.0) {
    voxel_downsample(source_in, o.voxel_size_m, downsampled_);
    source = &downsampled_;
  }
  const std::size_t n = source->points.size();
  result.source_points = int(n);
  const PointCloud& tgt = target.cloud();
  if (int(n) < std::max(o.min_points, 1) || int(target.size()) < std::max(o.min_points, 1) ||
      tgt.normals.size() != tgt.points.size()) {
    result.status = IcpStatus::kTooFewPoints;
    return result;
  }

  cache_->reset(n);

  const Centroid cs = centroid_and_radius(source->points);
  const double L = std::max(cs.rms_radius, 1e-6), inv_L = 1.0 / L;
  // Searching a little beyond the correspondence distance lets a point without a partner skip
  // later queries until it has moved by the difference.
  const float radius = 1.5f * float(o.max_correspondence_m);

  // Coarse to fine: the large first steps on every stride-th point. Each step re-queries about
  // every point it moves by more than a point spacing, so the subsample saves most of the
  // queries of a distant guess; the full cloud then starts close to its answer and its points
  // keep their nearest neighbours from one iteration to the next.
  std::size_t stride = 1;
  if (o.coarse_points > 0 && n >= 2 * std::size_t(o.coarse_points)) {
    stride = n / std::size_t(o.coarse_points);
  }
  const int min_inliers = std::max(o.min_points, 6);

  SE3 T = T_target_source_guess;
  for (int iteration = 1; iteration <= o.max_iterations; ++iteration) {
    const Eigen::Vector3d c = T * cs.centre;  // the source centroid in the target frame
    // At most the first half of the iterations are coarse: the full cloud always gets the rest
    // (and a subsample whose correspondences keep flipping cannot use them all up).
    if (iteration > o.max_iterations / 2) stride = 1;

    const NormalEquations eq = linearise(*source, stride, target, T, c, inv_L, o, *cache_, radius);
    last_queries_ += eq.queries;
    result.iterations = iteration;
    const bool coarse = stride > 1;
    result.coarse_iterations += coarse;
    if (eq.inliers < min_inliers) {
      if (coarse) {  // too sparse to register: the full cloud decides
        stride = 1;
        continue;
      }
      result.status = IcpStatus::kTooFewCorrespondences;
      result.converged = false;
      result.T_target_source = T;
      return result;
    }
    const Matrix6d H_scaled = eq.hessian();
    const DegeneracyReport degeneracy = analyse_degeneracy(H_scaled, c, L, o.min_eigenvalue_ratio);
    if (!coarse) {
      result.inliers = eq.inliers;
      result.rms_m = std::sqrt(NormalEquations::total(eq.sq) / eq.inliers);
      result.degeneracy = degeneracy;
      // Hessian and information in the right (source-frame) tangent at this linearisation
      // point: J_c = J_scaled S with S = diag(1, 1, 1, L, L, L), and delta_c = Ad(T_c^-1 T) eps.
      Vector6d s;
      s << 1, 1, 1, L, L, L;
      const Matrix6d H_c = s.asDiagonal() * H_scaled * s.asDiagonal();
      const Matrix6d A = (SE3::Translation(-c) * T).adjoint();
      result.hessian = A.transpose() * H_c * A;
      const double sigma_sq = NormalEquations::total(eq.weighted_sq) /
                              std::max(NormalEquations::total(eq.weight) - 6.0, 1.0);
      result.residual_sigma_m = std::max(std::sqrt(sigma_sq), o.min_residual_sigma_m);
      result.information = result.hessian / (result.residual_sigma_m * result.residual_sigma_m);
    }

    // Gauss-Newton step about the centroid, only along constrained directions.
    const Vector6d step_c = constrained_step(degeneracy, eq.gradient());
    const SE3 T_c = SE3::Translation(c);
    T = T_c * SE3::exp(step_c) * T_c.inverse() * T;
    if (coarse) {
      // Fine from the next iteration once the subsample's points move less than coarse_step_m.
      if (step_c.head<3>().norm() + step_c.tail<3>().norm() * L < o.coarse_step_m) stride = 1;
      continue;
    }
    result.T_target_source = T;
    if (step_c.head<3>().norm() < o.convergence_translation_m &&
        step_c.tail<3>().norm() < o.convergence_rotation_rad) {
      result.converged = true;
      result.status = IcpStatus::kConverged;
      return result;
    }
  }
  result.status = IcpStatus::kMaxIterations;
  result.converged = false;
  return result;
}

}  // namespace pg
