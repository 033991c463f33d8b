#pragma once
// A sensor's lights measured from labelled presses: the shading model's light positions, their
// colours and the specular share fitted so that the model's change of shading, from the
// undeformed gel's normal to each labelled normal, matches the change each frame shows against
// its no-contact reference (docs/renderer.md "Measuring a sensor's lights"). What a real
// sensor's frames need before the shading's inverse (pg/sim/shading_inversion.h) or a render
// with its lights can stand for it. The labels are a render's normals, or a real sensor's ball
// presses labelled by `patchgraph label-ball`.
#include <cstddef>
#include <functional>
#include <memory>

#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg {

struct ShadingFitOptions {
  int max_iterations = 100;
  // The pixels fitted: those whose labelled normal turns this far from the undeformed gel's
  // (the contact; elsewhere the change is noise) [rad].
  double min_turn_rad = 0.03;
  // At most this many pixels, taken evenly from all frames' (each pixel costs a shading per
  // parameter and iteration).
  std::size_t max_pixels = 40000;
  // Residuals beyond this are down-weighted (Huber): a label's error at a ball's rim, a speck
  // of dust [levels].
  double huber_levels = 20.0;
};

struct ShadingFitResult {
  // The start's sensor with the fitted lights (position_m, color, intensity), shading.specular
  // and (not blended) shading.ambient; everything else as the start's.
  SensorModel sensor;
  // Root mean square of the residual (the model's value less the frame's) over the fitted
  // channels, with the start's lights and with the fitted ones [levels].
  double rms_start_levels = 0, rms_levels = 0;
  std::size_t pixels = 0;    // pixels fitted
  std::size_t channels = 0;  // their channels
  int iterations = 0;
  bool converged = false;  // the cost stopped falling before max_iterations
};

class ShadingFit {
 public:
  // `blended`: the frames show the shading's change scaled by shading.background_gain on a real
  // background (a real sensor, a render onto a real background image), as ShadingInversion
  // reads them: the change from the reference is fitted. Else they show the shading itself (a
  // render on the synthetic background): each frame's values are fitted, and the ambient share
  // too, which cancels in a change. The model's exposure, diffuse share, shininess, camera and
  // gel stay the start's: exposure and diffuse only scale the lights' colours, which are fitted.
  ShadingFit(const SensorModel& start, bool blended, ShadingFitOptions options = {});
  ~ShadingFit();
  ShadingFit(ShadingFit&&) noexcept;
  ShadingFit& operator=(ShadingFit&&) noexcept;

  // Adds a labelled frame's contact pixels: its colour image, its no-contact reference and its
  // unit normals in S (+z out of the gel). The model's values are clipped to 8 bits as the
  // camera's are, so a channel clipped in the frame only bounds them. Returns the pixels it added
  // (0 for a frame without contact). Throws InputError when a size is not the sensor's.
  std::size_t add_frame(const ImageU8& color, const ImageU8& reference, const ImageF& normals);
  std::size_t pixels() const;

  // Levenberg-Marquardt on the lights' parameters, from the start's. `progress` is called after
  // each iteration with its number and the residual's RMS [levels]. Throws InputError when no
  // frame added a pixel.
  ShadingFitResult solve(const std::function<void(int, double)>& progress = {}) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace pg
