#pragma once
// The gel's surface as the camera sees it: per-pixel rays to the undeformed gel, the elastic
// deformation model, and the deformed surface's normals. Free functions over plain arrays.
#include <Eigen/Core>
#include <vector>

#include "pg/core/gel_rays.h"
#include "pg/core/pixel_rect.h"
#include "pg/core/sensor.h"

namespace pg {

// Per-sensor constants: one ray per pixel from the camera centre and where it meets the gel
// (GelRays, shared with the tracker), plus the bounds the renderer culls with.
struct GelGeometry : GelRays {
  std::vector<float> dir_x, dir_y;  // the rays' x and y, as plain arrays for vector loops
  float z_gel_min = 0;              // lowest undeformed gel z in view [m]
  // highest_z[b]: the highest undeformed gel point seen by any pixel whose gel point lies at
  // least sqrt(b * rho_sq_step) from the z axis [m] (-inf where there is none).
  std::vector<float> highest_z;
  float rho_sq_step = 0;  // [m^2]

  // An upper bound of z_gel over the pixels whose undeformed gel point lies at least
  // sqrt(rho_sq) from the z axis. A point p in front of the camera that a pixel's ray meets
  // before the undeformed gel lies below this bound at p's own rho_sq: the ray moves away from
  // the axis as z grows, so its gel point is farther out than p, and higher than p.
  float highest_gel_z_beyond(float rho_sq) const {
    const float b = rho_sq / rho_sq_step;
    const int n = int(highest_z.size());
    return highest_z[b < float(n - 1) ? int(b) : n - 1];
  }
};

GelGeometry make_gel_geometry(const SensorModel& sensor);

// Box-radius for which three box passes approximate a Gaussian of `sigma_px` (at least 1).
int gaussian_box_radius(double sigma_px);
// Three box passes of radius r along rows and three along columns over `rect`, values outside
// `rect` taken as zero at each pass (so `rect` should reach 3 r beyond any non-zero input, or
// end at the image's edge). src -> dst; scratch is image-sized and may be src, but not dst.
void gaussian_blur(const float* src, float* dst, float* scratch, int width, const PixelRect& rect,
                   int r);

// Elastic model: the coated gel surface cannot bend more sharply than rho =
// elastic.bend_radius_m. With r the rigid indentation (image-sized, zero away from the contact),
// u is the morphological closing of r by the paraboloid |d|^2 / (2 rho):
//   dilation  d(x) = max_q r(q) - |x - q|^2 / (2 rho)
//   erosion   u(x) = min_q d(q) + |x - q|^2 / (2 rho)
// i.e. the lowest surface above r that any paraboloid of curvature 1 / rho can touch from above.
// So u >= r (the gel never passes through the object); u = r wherever the indentation is no more
// sharply convex than 1 / rho (the gel takes the object's shape); the convex corner where a
// contact ends is rounded by a paraboloid that leaves the object tangentially and meets the
// undeformed gel tangentially (sink-in around the contact, and C1: no kink, no normal outliers).
// Both passes are separable, each an O(n) lower-envelope scan per line. Finally the surface is
// smoothed by a Gaussian of elastic.smoothing_m, keeping u >= r: u = max(r, G * closing(r)).
struct ElasticKernel {
  bool enabled = false;
  float alpha = 0;      // paraboloid coefficient 1 / (2 rho) in image units [m / px^2]
  int blur_radius = 0;  // box radius of the smoothing, 0 for none
  // 1 / (2 alpha k) for k = 0 .. the longest image line: where two parabolas k pixels apart meet.
  std::vector<float> inv_2alpha_k;
  // Pixels the dilation reaches beyond a contact whose deepest indentation is `depth_m`.
  int reach(float depth_m) const;
};
ElasticKernel make_elastic_kernel(const ElasticModel& model, float px_per_m, int longest_line);

// The deformed surface from the rigid indentation `rigid`, which is zero outside `contact` (its
// deepest value `deepest`). Returns the rectangle outside which u is zero; u is written on all
// of it and not touched elsewhere (so it must be zero there already). Work follows the contact:
// each line is scanned only over the span where its input is non-zero. scratch_a and scratch_b
// are image-sized.
PixelRect elastic_displacement(const ElasticKernel& kernel, int width, int height,
                               const PixelRect& contact, float deepest, const float* rigid,
                               float* scratch_a, float* scratch_b, float* u);

// Unit normals (pointing +z, out of the gel toward the object) of the surface displaced by u,
// over `rect`, written to normals (3 floats per pixel, image-sized). u is read on rect dilated
// by one pixel (clipped to the image), so it must be valid (or zero) there.
void surface_normals(const GelGeometry& g, const float* u, const PixelRect& rect, float* normals);

}  // namespace pg
