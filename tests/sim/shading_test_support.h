#pragma once
// Helpers shared by the tests of the shading's inverse and of its fit (test_render).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "../common/test_support.h"
#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg::testing_support {

// The angle [rad] between the unit normals of pixel i of two normal images.
inline double normal_angle(const ImageF& a, const ImageF& b, std::size_t i) {
  double dot = 0;
  for (int c = 0; c < 3; ++c) dot += double(a.data[3 * i + c]) * b.data[3 * i + c];
  return std::acos(std::clamp(dot, -1.0, 1.0));
}

// A textured stand-in for a real sensor's no-contact image (a blend only adds it), written to
// `path` in the running test's temporary folder, which goes with it.
struct TexturedBackground {
  TempDir dir;
  std::string path;
  explicit TexturedBackground(const SensorModel& sensor) : path(dir.str("bg.png")) {
    ImageU8 bg(sensor.camera.width, sensor.camera.height, 3);
    for (int y = 0; y < bg.height; ++y)
      for (int x = 0; x < bg.width; ++x)
        for (int c = 0; c < 3; ++c)
          bg.at(x, y, c) = std::uint8_t(80 + 40 * c + 20 * std::sin(0.2 * x + 0.3 * y + c));
    write_image(path, bg);
  }
};

}  // namespace pg::testing_support
