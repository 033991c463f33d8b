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
// coordinates x = [rho_c; L phi] (degeneracy.h).
struct NormalEquations {
  double H[21] = {};  // upper triangle of sum w J J^T, row by row
  double g[6] = {};   // sum w r J
  double weighted_sq = 0;  // sum w r^2 [m^2]
  double weight = 0;       // sum w
  double sq = 0;           // sum r^2 over inliers [m^2]
  int inliers = 0;
  long queries = 0;

  // Adds m terms stored by column (J[a][i], w[i], r[i]): 27 dot products over the terms,
  // which vectorise, instead of 27 read-modify-writes per term.
  template <int kCapacity>
  void add_terms(const double (&J)[6][kCapacity], const double* w, const double* r, int m) {
    double wJ[6][kCapacity];
    for (int a = 0; a < 6; ++a) {
      for (int i = 0; i < m; ++i) wJ[a][i] = w[i] * J[a][i];
    }
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      double ga = 0;
      for (int i = 0; i < m; ++i) ga += wJ[a][i] * r[i];
      g[a] += ga;
      for (int b = a; b < 6; ++b) {
        double h = 0;
        for (int i = 0; i < m; ++i) h += wJ[a][i] * J[b][i];
        H[k++] += h;
      }
    }
    for (int i = 0; i < m; ++i) {
      weighted_sq += w[i] * r[i] * r[i];
      weight += w[i];
      sq += r[i] * r[i];
    }
    inliers += m;
  }
  void add(const NormalEquations& o) {
    for (int k = 0; k < 21; ++k) H[k] += o.H[k];
    for (int k = 0; k < 6; ++k) g[k] += o.g[k];
    weighted_sq += o.weighted_sq;
    weight += o.weight;
    sq += o.sq;
    inliers += o.inliers;
    queries += o.queries;
  }
  Matrix6d hessian() const {
    Matrix6d M;
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b) M(a, b) = M(b, a) = H[k++];
    }
    return M;
  }
  Vector6d gradient() const { return Eigen::Map<const Vector6d>(g); }
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
// coordinates about c, summed over the source points in parallel (oneTBB reduction).
NormalEquations linearise(const PointCloud& source, const PointCloudTree& target, const SE3& T,
                          const Eigen::Vector3d& c, double inv_L, const IcpOptions& o,
                          CorrespondenceCache& cache, float radius) {
  const Eigen::Matrix3f R = T.rotation_matrix().cast<float>();
  const Eigen::Vector3f t = T.translation().cast<float>();
  const Eigen::Vector3f cf = c.cast<float>();
  const float max_corr = float(o.max_correspondence_m);
  const float max_corr_sq = max_corr * max_corr;
  const std::vector<Eigen::Vector3f>& src = source.points;
  const PointCloud& tgt = target.cloud();
  return tbb::parallel_reduce(
      tbb::blocked_range<std::size_t>(0, src.size(), kGrainSize), NormalEquations(),
      [&](const tbb::blocked_range<std::size_t>& range, NormalEquations acc) {
        constexpr int kChunk = 64;  // terms gathered before they are summed
        double J[6][kChunk], wc[kChunk], rc[kChunk];
        int m = 0;
        for (std::size_t i = range.begin(); i != range.end(); ++i) {
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
    case IcpStatus::kConverged: return "converged";
    case IcpStatus::kMaxIterations: return "max iterations";
    case IcpStatus::kTooFewPoints: return "too few points";
    case IcpStatus::kTooFewCorrespondences: return "too few correspondences";
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

  SE3 T = T_target_source_guess;
  for (int iteration = 1; iteration <= o.max_iterations; ++iteration) {
    const Eigen::Vector3d c = T * cs.centre;  // the source centroid in the target frame

    const NormalEquations eq = linearise(*source, target, T, c, inv_L, o, *cache_, radius);
    last_queries_ += eq.queries;
    result.iterations = iteration;
    result.inliers = eq.inliers;
    if (eq.inliers < std::max(o.min_points, 6)) {
      result.status = IcpStatus::kTooFewCorrespondences;
      result.converged = false;
      result.T_target_source = T;
      return result;
    }
    result.rms_m = std::sqrt(eq.sq / eq.inliers);
    const Matrix6d H_scaled = eq.hessian();
    result.degeneracy = analyse_degeneracy(H_scaled, c, L, o.min_eigenvalue_ratio);

    // Hessian and information in the right (source-frame) tangent at this linearisation point:
    // J_c = J_scaled S with S = diag(1, 1, 1, L, L, L), and delta_c = Ad(T_c^-1 T) eps.
    Vector6d s;
    s << 1, 1, 1, L, L, L;
    const Matrix6d H_c = s.asDiagonal() * H_scaled * s.asDiagonal();
    const Matrix6d A = (SE3::Translation(-c) * T).adjoint();
    result.hessian = A.transpose() * H_c * A;
    const double sigma_sq = eq.weighted_sq / std::max(eq.weight - 6.0, 1.0);
    result.residual_sigma_m = std::max(std::sqrt(sigma_sq), o.min_residual_sigma_m);
    result.information = result.hessian / (result.residual_sigma_m * result.residual_sigma_m);

    // Gauss-Newton step about the centroid, only along constrained directions.
    const Vector6d step_c = constrained_step(result.degeneracy, eq.gradient());
    const SE3 T_c = SE3::Translation(c);
    T = T_c * SE3::exp(step_c) * T_c.inverse() * T;
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
