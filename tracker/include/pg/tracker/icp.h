#pragma once
// Point-to-plane ICP: the registration inside the image-to-image (eq. 5) and image-to-patch
// (eq. 6) factors. Gauss-Newton on SE(3) with a robust kernel, correspondences from a reusable
// k-d tree, a oneTBB-parallel reduction of the 6x6 system, and a degeneracy report whose
// unconstrained directions the updates leave at the initial guess.
#include <memory>

#include "pg/core/se3.h"
#include "pg/tracker/degeneracy.h"
#include "pg/tracker/kd_tree.h"
#include "pg/tracker/point_cloud.h"
#include "pg/tracker/point_to_plane.h"

namespace pg {

class CorrespondenceCache;

// Full-cloud iterations that IcpOptions::cycle_extent_m compares.
constexpr int kCycleIterations = 4;

struct IcpOptions {
  int max_iterations = 30;
  double max_correspondence_m = 1e-3;  // pairs farther apart are not used [m]
  RobustKernel kernel = RobustKernel::kHuber;
  double kernel_scale_m = 1e-4;  // Huber: quadratic within; Tukey: zero weight beyond [m]
  // The residual's direction: the mean of the target point's normal and the moved source point's
  // (a symmetric point-to-plane objective), or the target's alone (false; also for a source
  // without normals, or a pair whose normals face apart). Two exact samples of a sphere or a
  // cylinder give zero along their mean normal, but the distance curvature x spacing^2 / 2 from
  // the target's tangent plane: on a 1 mm rounding sampled every 0.16 mm that is ~3 um, as much
  // as a frame's motion, and it biases the weakly seen rotations of small curved contacts.
  bool symmetric = true;
  // For a source with normals, once a step moves the cloud by less than 0.02 mm: a pair whose
  // two normals (the target point's and the moved source point's) differ by more than this is
  // not used (0: every pair), with either objective. Near the answer such a pair straddles a
  // crease, a toy brick's stud rim say, where the nearest sample of the other frame lies on the
  // other face: its mean normal is neither face's, and its target normal is the wrong face's
  // for the source point. From a distant guess the same pairs often pull the cloud in, hence
  // the wait for a small step (docs/tracker_geometry.md) [rad].
  double max_normal_angle_rad = 0.25;
  // Converged when an update moves the source centroid by less than this [m] and rotates by
  // less than convergence_rotation_rad [rad].
  double convergence_translation_m = 1e-7;
  double convergence_rotation_rad = 1e-6;
  // Converged as well when the last kCycleIterations full-cloud iterations started within this of
  // the last one: the centroid's displacement plus the cloud's radius times the angle [m]. Near
  // its answer the iteration can fall into a cycle, nearest neighbours and float rounding
  // handing two or more poses back and forth for ever, with every step above the thresholds
  // (docs/tracker_geometry.md, "Cycles"); 0: off.
  double cycle_extent_m = 1e-6;
  int min_points = 20;      // fewer source points or correspondences: not converged [-]
  double voxel_size_m = 0;  // downsample the source to this voxel edge first; 0: off [m]
  // Coarse to fine: while the steps are large, iterate on an evenly strided subsample of about
  // coarse_points source points (0: off; clouds under twice this size are never subsampled),
  // until a step moves the subsample by less than coarse_step_m (or half of max_iterations have
  // run); the iterations after that use every point, so the result is the full cloud's.
  int coarse_points = 128;
  double coarse_step_m = 2e-6;  // [m]
  // Degeneracy: a direction is unconstrained when its eigenvalue of the scaled Hessian (see
  // degeneracy.h) is below this fraction of the largest [-].
  double min_eigenvalue_ratio = 5e-3;
  // Three free directions rolling the contact about a centre farther than this are taken for a
  // flat face's slides and spin (DegeneracyReport::flat_radius_m); 0: off, as for exact normals,
  // where a large ball's rolls are real. `track` sets 0.02 for learned normals [m].
  double flat_radius_m = 0;
  // Floor of the residual sigma used for the information matrix (exact synthetic data would
  // otherwise give infinite information) [m].
  double min_residual_sigma_m = 1e-5;
};

enum class IcpStatus {
  kConverged,
  kMaxIterations,          // the last update was still above the thresholds, and no cycle
  kTooFewPoints,           // source (after downsampling) or target below min_points, or no normals
  kTooFewCorrespondences,  // fewer than min_points pairs within max_correspondence_m
};
const char* to_string(IcpStatus status);

struct IcpResult {
  SE3 T_target_source;  // the guess when the registration failed early
  // Gauss-Newton Hessian sum_i w_i J_i^T J_i at the optimum, in the right (source-frame) tangent:
  // T_true = T_target_source * exp(eps), eps = [rho; phi] [m; rad].
  Matrix6d hessian = Matrix6d::Zero();
  // hessian / sigma^2: eps ~ N(0, information^-1). Near-zero along unconstrained directions.
  // Units: 1/m^2 (translation block), 1/(m rad), 1/rad^2.
  Matrix6d information = Matrix6d::Zero();
  double residual_sigma_m = 0;  // weighted RMS point-to-plane residual, floored [m]
  int inliers = 0;              // correspondences within max_correspondence_m with weight > 0
  double rms_m = 0;             // RMS point-to-plane residual of the inliers [m]
  bool converged = false;
  IcpStatus status = IcpStatus::kTooFewPoints;
  int iterations = 0;           // Gauss-Newton linearisations, coarse ones included
  int coarse_iterations = 0;    // of which on the subsample (IcpOptions::coarse_points)
  int source_points = 0;        // after downsampling
  DegeneracyReport degeneracy;  // at the last linearisation
};

// Holds the options and the per-point scratch (downsampled source, correspondence cache), so
// repeated calls with clouds of similar size allocate nothing. Not thread-safe (one per thread);
// parallel inside.
class PointToPlaneIcp {
 public:
  explicit PointToPlaneIcp(const IcpOptions& options = IcpOptions());
  ~PointToPlaneIcp();
  PointToPlaneIcp(PointToPlaneIcp&&) noexcept;
  PointToPlaneIcp& operator=(PointToPlaneIcp&&) noexcept;

  // Aligns source (points, normals optional) to target (points with normals) starting from the
  // guess. The target tree is only read, so one tree serves many calls (and threads). Source
  // points (or normals) that are not finite are left out.
  IcpResult align(const PointCloud& source, const PointCloudTree& target,
                  const SE3& T_target_source_guess);

  const IcpOptions& options() const { return options_; }
  IcpOptions& options() { return options_; }
  // Nearest-neighbour queries in the last align() call (the rest reused a provably unchanged
  // correspondence).
  long last_queries() const { return last_queries_; }

 private:
  IcpOptions options_;
  PointCloud finite_;  // the source's finite points, when it has others
  PointCloud downsampled_;
  std::unique_ptr<CorrespondenceCache> cache_;  // nearest neighbours kept between iterations
  long last_queries_ = 0;
};

}  // namespace pg
