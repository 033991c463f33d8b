#pragma once
// The gel's elastic deformation around a contact (ElasticModel): from the rigid indentation (the
// gel pushed in exactly where the object penetrates it, TACTO's model) to the surface a coated
// gel takes, with its rounded rim and sink-in. The renderer deforms its gel with it, and
// label-ball synthesises a ball press's labels with it. Free functions over plain arrays.
#include <vector>

#include "pg/core/image.h"
#include "pg/core/pixel_rect.h"
#include "pg/core/sensor.h"

namespace pg {

// A Gaussian of sigma_px pixels, sampled at whole pixels out to 3 sigma and normalised: weights[k]
// for the offsets +-k. No weights (no blur) for a sigma whose neighbouring weight would be below
// 1e-6 of the centre's (under 0.19 px), where the blur would change nothing.
struct GaussianKernel {
  std::vector<float> weights;
  int radius() const { return weights.empty() ? 0 : int(weights.size()) - 1; }
};
GaussianKernel gaussian_kernel(double sigma_px);
// The kernel along rows, then along columns, over `rect`, values outside `rect` taken as zero
// (so `rect` should reach kernel.radius() beyond any non-zero input, or end at the image's
// edge). src -> dst; scratch is image-sized and may be src, but not dst. Needs a kernel with
// weights.
void gaussian_blur(const float* src, float* dst, float* scratch, int width, const PixelRect& rect,
                   const GaussianKernel& kernel);

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
  GaussianKernel blur;  // the smoothing (no weights: none)
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

// The same for a whole image: `rigid` (width x height x 1 [m], zero away from the contact, e.g.
// sphere_indentation's) deformed under `model` at `px_per_m` (GelRays::px_per_m); a copy of it
// when the model is off.
ImageF elastic_indentation(const ElasticModel& model, double px_per_m, const ImageF& rigid);

}  // namespace pg
