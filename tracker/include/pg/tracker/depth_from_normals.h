#pragma once
// Normals -> gel indentation (paper section IV-B, eq. 4): surface gradients from the normal
// image, integrated by a Poisson solve with a zero (Dirichlet) boundary at the undisturbed gel.
//
// The normals are those of the deformed, curved gel, seen in perspective. With t the camera depth
// of the gel surface along pixel (x, y)'s ray d = ((x - cx) / fx, (y - cy) / fy, 1), the tangent
// dP/dx = t_x d + t (1 / fx, 0, 0) is perpendicular to the normal n, which gives eq. 4 in
// perspective form for the log depth:
//   d ln t / dx = -n_x / (fx n.d),   d ln t / dy = -n_y / (fy n.d)       [per pixel]
// (for an orthographic camera n.d = n_z: the paper's dz/dx = n_x / n_z up to the sign convention).
// Only the difference from a reference (no-contact) normal image is integrated, so the curved
// gel's own shape cancels: w = ln(t / t_gel) solves  lap w = div(g - g_ref), w = 0 where the gel
// is undisturbed, and the indentation is u = t_gel - t = t_gel (1 - exp(w)).
#include <array>
#include <cstdint>
#include <vector>

#include "pg/core/gel_rays.h"
#include "pg/core/image.h"
#include "pg/core/pixel_rect.h"
#include "pg/core/sensor.h"
#include "pg/tracker/poisson_dst.h"

namespace pg {

enum class DepthIntegration { kParity, kAveraged };

// The pixel size on the gel at which DepthOptions::min_normal_dot_ray holds as given, about the
// DIGIT's at 120x160 (0.159 mm at the gel's centre) [m].
constexpr double kGuardPitchM = 0.15e-3;

// The lengths the front end takes a normal to be unit at (every source here gives unit normals,
// a 16-bit PNG's to 3e-5, a network's normalised): a normal image left in a PNG's encoding,
// (n + 1) / 2, is about 1.22 long on a flat gel and is rejected, rather than read as a contact
// over most of the image (the band had been 0.5-1.5, which took it).
constexpr float kMinNormalLength = 0.9f, kMaxNormalLength = 1.1f;

struct DepthOptions {
  // Guard of eq. 4: n.d (n_z for an orthographic camera) is clamped to at least this, so a
  // normal nearly perpendicular to its ray cannot produce an unbounded slope [-]. It holds for
  // pixels of kGuardPitchM or more on the gel; on finer ones the slope it allows grows with the
  // resolution (DepthFromNormals::min_normal_dot_ray()).
  double min_normal_dot_ray = 0.2;
  // A pixel is disturbed (deformed) when its normal differs from the reference normal by more
  // than this angle [rad]. Raise it above the normal estimator's noise on real data.
  double disturbed_angle_rad = 0.005;
  // Integrate only over the disturbed pixels' bounding box plus a margin (false: the whole
  // image). Either way the grid is padded so its DST sizes factor into small primes.
  bool crop = true;
  int crop_margin_px = 4;                         // [px], at least 1
  DstBackend dst_backend = DstBackend::kRealFft;  // see poisson_dst.h
  bool measure_fft_plans = false;  // FFTW_MEASURE plans: 0.1-0.6 s on the first frame of a size
  // How the gradients are integrated.
  //  kParity: the renderer's normal at a pixel is the central difference of the surface points
  //   of its two neighbours, so g(x) = (ln t(x+1) - ln t(x-1)) / 2 exactly: a forward
  //   difference on the sub-grid of the pixels of the other parity. Each of the four sub-grids
  //   (x even/odd, y even/odd) is integrated by its own Poisson solve at a quarter of the size,
  //   which recovers the rendered indentation to float precision, kinks included.
  //  kAveraged: one Poisson solve with each difference between neighbours taken as the mean of
  //   their gradients; at a kink (the gel folding over a rigid edge or rim) that is about a pixel
  //   off, and the least squares spreads it over the contact (measured on the benchmark's cube:
  //   13-19 um RMS in the shallowest 0.1 mm, faces tilted by a few mrad).
  DepthIntegration integration = DepthIntegration::kParity;
};

struct DepthResult {
  ImageF depth;      // indentation u [m] along the camera z axis, width x height x 1
  PixelRect window;  // the Poisson grid in image coordinates (may reach past the image)
  // Edges of the image (left, top, right, bottom) across which the grid held the image
  // mirrored (DepthFromNormals::compute).
  std::array<bool, 4> mirrored{};
  PixelRect disturbed_box;  // bounding box of the disturbed pixels (empty: none)
  int disturbed_pixels = 0;
  // NaN, inf, far from unit length or n.d <= 0 (seen from behind along the pixel's ray d): their
  // gradient is interpolated from the valid pixels beside them in the row (a dead pixel inside
  // a contact leaves no dent).
  int invalid_normals = 0;
  int clamped_normals = 0;  // n.d below min_normal_dot_ray inside the grid, clamped
};

// Coordinates the per-sensor constants (rays, reference gradients), the FFTW plan cache and the
// scratch buffers, so a frame allocates nothing once the sizes have been seen. Not thread-safe:
// one per thread.
class DepthFromNormals {
 public:
  // reference_normals: a no-contact frame's normal image (width x height x 3, in S), e.g. the
  // normal estimator's output on a real sensor's no-contact image. Empty: the undeformed gel of
  // the sensor model (undeformed_gel_normals). Throws InputError on a size mismatch or
  // non-finite reference values.
  DepthFromNormals(const SensorModel& sensor, const DepthOptions& options,
                   const ImageF& reference_normals = ImageF());

  // Fills `out` (its buffers are reused across calls). Throws InputError if `normals` is not
  // width x height x 3.
  // mirror_edges (left, top, right, bottom): edges of the image a contact reaches. A contact
  // goes on past the image's edge, where nothing is known; integrated with the gradients there
  // zero (the flat gel), as across the other edges, its depth is pulled toward zero at the edge
  // and tilts. Across each of these edges that the disturbed pixels reach, the grid holds the
  // image mirrored, its gradients reflected: the solution is symmetric about the edge, so nothing
  // past it pulls (the least-squares boundary).
  void compute(const ImageF& normals, DepthResult& out,
               const std::array<bool, 4>& mirror_edges = {});

  const GelRays& rays() const { return rays_; }
  const DepthOptions& options() const { return options_; }
  // The guard in force: options().min_normal_dot_ray, with the slope it allows,
  // tan(acos(n.d)), widened by kGuardPitchM over the pixel's size on the gel at the image's
  // centre where that is above 1. A rendered normal is a central difference over two pixels, so
  // a wall (a stud's rim on the rigid gel) shows a slope that grows with the resolution: at
  // 480x640 the fixed guard flattened the rims and turned the toy brick's estimate 0.036 rad.
  float min_normal_dot_ray() const { return min_dot_; }
  const PoissonDstSolver& solver() const { return solver_; }

 private:
  DepthOptions options_;
  GelRays rays_;
  float min_dot_ = 0;
  ImageF reference_normals_;
  std::vector<float> reference_gradient_;  // g_ref per pixel: (d ln t / dx, d ln t / dy)
  std::vector<float> gx_, gy_;             // g - g_ref over the grid plus a 1-pixel ring
  // For each column (row) of that ring-padded grid: the image column (row) it reads, -1 for none,
  // and the sign its gradient's x (y) component takes there (-1 across a mirrored edge).
  std::vector<int> source_x_, source_y_;
  std::vector<float> sign_x_, sign_y_;
  std::vector<std::uint8_t> flags_;  // one row's disturbed flags
  std::vector<float> w_;             // ln(t / t_gel) over the grid (kParity)

  // Solve for w over the nx x ny grid from gx_, gy_; the result is valid until the next solve.
  const float* integrate_averaged(int nx, int ny);
  const float* integrate_parity(int nx, int ny);
  PoissonDstSolver solver_;
};

}  // namespace pg
