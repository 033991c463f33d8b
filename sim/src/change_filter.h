#pragma once
// The change a blended frame shows (frame - reference), Wiener-filtered for the blend's blur and
// the camera's noise. TACTO's blend, as the renderer does it, adds the shading's change blurred by
// a Gaussian of shading.background_blur_m (0.2 mm, 1.26 px at 120x160) to a real background, and
// the camera adds its noise after. The blur leaves the change almost nothing finer than a few
// pixels (its transfer is 0.06 at 0.3 cycles per pixel), so what the frame holds there is mostly
// noise; read pixel by pixel, that noise, halved in the change by the blend's gain, doubles in the
// normals. Per frequency f the filter is H = G (1 + k) / (G^2 + k), G the blur's transfer and k
// the noise-to-signal ratio: about 1 where the blur keeps the change (a little above 1 where it
// dims it), about G (1 + k) / k where noise is all that is left, and 1 for a uniform change.
// ShadingInversion reads a blended frame through it, and ShadingFit fits the lights to it
// (docs/learned_normals.md "Inverting the shading").
#include <cstddef>
#include <vector>

#include "pg/core/image.h"

namespace pg {

class ChangeFilter {
 public:
  // The noise-to-signal ratio k: chosen on the training presses of
  // scripts/train_normals.sh rendered onto the real DIGIT background (sphere and cube, 100
  // frames; a scratch FFT version of the filter): the inverse's contact angle 5.40 / 6.22 deg as
  // the frames are, 3.92 / 4.32 at 0.1, 2.72 / 3.42 at 0.3, 2.48 / 3.41 at 0.5, 2.35 / 3.64 at 1.
  static constexpr double kNoiseToSignal = 0.3;

  // `blur_px`: the blend's Gaussian sigma in pixels (background_blur_m times the image scale at
  // the gel); 0 (or one too small to blur, as the renderer's gaussian_kernel has it) leaves every
  // change as it is: without the blur, the noise is spread over every frequency the change has.
  explicit ChangeFilter(double blur_px, double noise_to_signal = kNoiseToSignal);

  bool active() const { return !kernel_.empty(); }
  int radius() const { return radius_; }

  // Per pixel of `pixels` (indices into the width x height image), the filtered change of each
  // channel, frame minus reference [levels], into out[3 j + c]. Pixels beyond the image's edge
  // are taken mirrored across it. `color` and `reference` are the same size, 3 channels.
  void change_at(const ImageU8& color, const ImageU8& reference, const std::vector<int>& pixels,
                 std::vector<float>& out) const;

 private:
  int radius_ = 0;
  std::vector<float> kernel_;  // (2 radius + 1)^2, row-major
};

}  // namespace pg
