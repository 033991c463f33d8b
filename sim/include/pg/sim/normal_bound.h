#pragma once
// How much one colour frame can tell about the gel's normal: the Cramer-Rao bound of an unbiased
// per-pixel estimate of the normal's two tilts from the pixel's three colour channels, through the
// sensor's shading (its lights, Blinn-Phong, no shadows, the synthetic background) and its camera
// noise. A question of the sensor's design (where its lights sit, its exposure) that needs no
// press rendered (docs/renderer.md, "How much a frame tells").
#include <array>
#include <memory>

#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg {

struct NormalBound {
  // Per pixel, sigma sqrt(trace((J^T J)^-1)) [rad], J the colour's Jacobian [levels / rad] with
  // respect to the normal's two tilts: the angular standard deviation the best unbiased estimate
  // of that pixel's normal can reach. +inf where the colour cannot tell both tilts apart (one
  // light's terms vanish there, or channels are clipped). width x height x 1.
  ImageF angle_rad;
  // The shaded colour of those normals before it is clipped to 8 bits, per channel (R, G, B):
  // the brightest pixel [levels] and the fraction of pixels at 255 or above (or at 0).
  std::array<double, 3> brightest{}, clipped_fraction{};
};

// A sensor's bounds: its per-pixel rays, undeformed gel normals and lights, made once for any
// number of noise levels and tilts (the rays are most of one bound's work).
class NormalBounds {
 public:
  // Throws InputError for a sensor a sensor file could not give (check_sensor_model).
  explicit NormalBounds(const SensorModel& sensor);
  ~NormalBounds();

  // The bound for the undeformed gel's normal at each pixel turned by tilt_rad toward the image
  // direction azimuth_rad (0: +x), with camera noise of sigma levels (> 0) in each channel. A
  // channel clipped at 0 or 255 tells nothing: its change is not seen. Throws InputError for
  // sigma <= 0 or a tilt outside [0, pi / 2).
  NormalBound compute(double sigma, double tilt_rad = 0, double azimuth_rad = 0) const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

// NormalBounds(sensor).compute(sigma, tilt_rad, azimuth_rad), for one bound.
NormalBound normal_bound(const SensorModel& sensor, double sigma, double tilt_rad = 0,
                         double azimuth_rad = 0);

}  // namespace pg
