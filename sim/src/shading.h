#pragma once
// Shading of the gel's reflective coating by the sensor's point lights, optional self-shadowing
// of the deformed gel, and the pixel noise.
#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

#include "gel_surface.h"
#include "pg/core/error.h"
#include "pg/core/sensor.h"

namespace pg {

struct ShadingLight {
  Eigen::Vector3f position;  // in S [m]
  Eigen::Vector3f color;     // colour * intensity * exposure
  float d0_sq = 1;           // squared distance to the gel centre: fall-off is 1 there
};

struct Shader {
  ShadingModel model;
  std::vector<ShadingLight> lights;
  Eigen::Vector3f camera;  // camera centre in S
};
Shader make_shader(const SensorModel& sensor);

// Throws InputError "WHAT WxHxC: the sensor's images are WxHx3" unless `image` (an ImageU8 or
// ImageF) is width x height x 3: a frame the shading is read from (ShadingInversion) or fitted
// to (ShadingFit), or its reference or normals.
template <typename Image>
void check_sensor_image(const char* what, const Image& image, int width, int height) {
  if (image.same_shape(width, height, 3) && image.data.size() != image.shape_values()) {
    // A camera buffer wrapped by hand at another size: it had been read past its end.
    throw InputError(std::string(what) + " " + std::to_string(width) + "x" +
                     std::to_string(height) + "x3 holds " + std::to_string(image.data.size()) +
                     " values, not " + std::to_string(image.shape_values()));
  }
  if (image.same_shape(width, height, 3)) return;
  throw InputError(std::string(what) + " " + std::to_string(image.width) + "x" +
                   std::to_string(image.height) + "x" + std::to_string(image.channels) +
                   ": the sensor's images are " + std::to_string(width) + "x" +
                   std::to_string(height) + "x3");
}

// Linear RGB in [0, ~1] of a run of gel points p with outward normals n (+z toward the
// object), in structure-of-arrays form so that the compiler vectorises it; the coating is lit
// and seen from the camera side, so it reflects along -n. rgb is interleaved (3 per pixel).
// `visibility` holds count values in [0, 1] per light (light-major, shadows), or nullptr.
struct ShadeSpan {
  int count = 0;
  const float *px, *py, *pz, *nx, *ny, *nz;
  const float* visibility = nullptr;
};
void shade_span(const Shader& shader, const ShadeSpan& span, float* rgb);

// Gaussian pixel noise: a fixed table of normal samples read from an offset chosen per frame
// from the seed. Cheap enough to add to every pixel of every frame: the values are 16-bit fixed
// point (value * 2^frac_bits) and the samples 8-bit, in steps of an odd number of fixed-point
// units chosen so that the table's largest sample just fits (about sigma / 24 for any sigma),
// so that a frame reads little memory and the sum is done in 16-bit vector lanes.
class NoiseTable {
 public:
  explicit NoiseTable(float sigma);
  // Fixed-point scale of the values apply() takes.
  int frac_bits() const { return bits_; }
  std::int16_t to_fixed(float value_255) const {
    return std::int16_t(value_255 * float(1 << bits_) + 0.5f);
  }
  // Adds sigma * N(0, 1) to each of n fixed-point values (0-255 scale), rounds and clamps to 8
  // bits. `position` is the index of values[0] in the frame, so a frame may be done in pieces.
  void apply(const std::int16_t* values, std::uint8_t* out, std::size_t n, std::uint64_t seed,
             std::size_t position = 0) const;
  // The table: sample i adds samples()[i] * step() fixed-point units (1/2^frac_bits levels).
  const std::vector<std::int8_t>& samples() const { return samples_; }
  int step() const { return step_; }

 private:
  std::vector<std::int8_t> samples_;
  int bits_ = 0;
  int step_ = 1;
};

std::uint64_t splitmix64(std::uint64_t x);

}  // namespace pg
