#pragma once
// Normals read from a colour frame without a network: the sensor's own shading model (its
// lights, Blinn-Phong, exposure) inverted pixel by pixel, by least squares on the pixel's colour
// channels. Exact only where the frames come from that model (renders of that sensor); it needs
// no training, and it is the reference a learned model's normals can be set against
// (docs/learned_normals.md "Inverting the shading").
#include <memory>

#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg {

class ShadingInversion {
 public:
  // `blended`: the frames are TACTO's blend of the shading's change onto a real background image
  // (out = bg + blur(sim - sim_bg) * background_gain; a dataset whose DatasetInfo::background is
  // set), or a real sensor's change from its no-contact image; the change is read through the
  // Wiener filter for a blur of shading.background_blur_m (sim/src/change_filter.h; 0: as it
  // is). Else the frames are the shading itself, as the synthetic background renders it.
  ShadingInversion(const SensorModel& sensor, bool blended);
  ~ShadingInversion();
  ShadingInversion(ShadingInversion&&) noexcept;
  ShadingInversion& operator=(ShadingInversion&&) noexcept;

  // Unit normals in S (+z out of the gel, as a dataset's normal images), width x height x 3.
  // Pixels outside the frame's changed regions (pg/core/image_change.h: beyond the camera's
  // noise, larger than specks, and a pixel around them) keep the undeformed gel's normal; each
  // changed pixel's normal is the one whose shading best matches its colour channels (a clipped
  // channel only bounds it). Where the shading cannot tell a tilt (one light's terms vanish),
  // the estimate stays near the undeformed normal. Throws InputError when `color` or `reference`
  // is not the sensor's width x height x 3.
  ImageF normals(const ImageU8& color, const ImageU8& reference) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace pg
