#pragma once
// Shading of the gel's reflective coating by the sensor's point lights, optional self-shadowing
// of the deformed gel, and the pixel noise.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gel_surface.h"
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

// Linear RGB in [0, ~1] of a gel point p with outward normal n (+z toward the object); the
// coating is lit and seen from the camera side, so it reflects along -n. `visibility[k]` in
// [0, 1] scales light k (shadows), or nullptr for fully lit.
Eigen::Vector3f shade(const Shader& shader, const Eigen::Vector3f& p, const Eigen::Vector3f& n,
                      const float* visibility);

// The same for a run of pixels in structure-of-arrays form, written so that the compiler
// vectorises it: points p, outward normals n; rgb is interleaved (3 per pixel). `visibility`
// holds count values per light (light-major), or nullptr.
struct ShadeSpan {
  int count = 0;
  const float *px, *py, *pz, *nx, *ny, *nz;
  const float* visibility = nullptr;
};
void shade_span(const Shader& shader, const ShadeSpan& span, float* rgb);

// Fraction of each light that reaches the surface point of pixel i, marching from the point
// toward the light over the deformed height field u (valid on `rect`, undeformed elsewhere):
// the light is blocked where the path leaves the gel through its deformed surface.
void light_visibility(const Shader& shader, const GelGeometry& g, const SensorModel& sensor,
                      const float* u, const PixelRect& rect, int i, float* visibility);

// Gaussian pixel noise: a fixed table of unit normal samples read from an offset chosen per
// frame from the seed. Cheap enough to add to every pixel of every frame.
class NoiseTable {
 public:
  NoiseTable();
  // Adds sigma * N(0, 1) to each of n values (0-255 scale), rounds and clamps to 8 bits.
  // `position` is the index of values_255[0] in the frame, so a frame may be done in pieces.
  void apply(const float* values_255, std::uint8_t* out, std::size_t n, float sigma,
             std::uint64_t seed, std::size_t position = 0) const;

 private:
  std::vector<float> samples_;
};

std::uint64_t splitmix64(std::uint64_t x);

}  // namespace pg
