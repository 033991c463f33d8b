#include "pg/sim/primitives.h"

#include <cmath>
#include <stdexcept>
#include <string>

#include "pg/core/numbers.h"

namespace pg {

TriangleMesh make_uv_sphere(float radius_m, int rings, int segments) {
  // Fewer rings or segments make no closed surface (one ring's indices had pointed past the
  // vertices); a radius that is not positive, none at all.
  if (rings < 2 || segments < 3 || !(radius_m > 0) || !std::isfinite(radius_m)) {
    throw std::invalid_argument("make_uv_sphere: radius " + std::to_string(radius_m) + ", " +
                                std::to_string(rings) + " rings, " + std::to_string(segments) +
                                " segments; a sphere needs a positive radius, 2 rings and 3 "
                                "segments at least");
  }
  TriangleMesh m;
  m.vertices.push_back({0, 0, radius_m});
  for (int r = 1; r < rings; ++r) {
    const float theta = float(kPi) * float(r) / float(rings);
    for (int s = 0; s < segments; ++s) {
      const float phi = 2.0f * float(kPi) * float(s) / float(segments);
      m.vertices.push_back(radius_m * Eigen::Vector3f(std::sin(theta) * std::cos(phi),
                                                      std::sin(theta) * std::sin(phi),
                                                      std::cos(theta)));
    }
  }
  m.vertices.push_back({0, 0, -radius_m});
  const int south = int(m.vertices.size()) - 1;
  auto ring = [&](int r, int s) { return 1 + (r - 1) * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) {
    m.triangles.push_back({0, ring(1, s), ring(1, s + 1)});
    m.triangles.push_back({south, ring(rings - 1, s + 1), ring(rings - 1, s)});
  }
  for (int r = 1; r < rings - 1; ++r) {
    for (int s = 0; s < segments; ++s) {
      m.triangles.push_back({ring(r, s), ring(r + 1, s), ring(r + 1, s + 1)});
      m.triangles.push_back({ring(r, s), ring(r + 1, s + 1), ring(r, s + 1)});
    }
  }
  return m;
}

TriangleMesh make_box(const Eigen::Vector3f& half) {
  // A negative extent turns the box inside out (it had pressed nothing); zero flattens it.
  if (!(half.minCoeff() > 0) || !half.allFinite()) {
    throw std::invalid_argument("make_box: half extents must be positive, got (" +
                                std::to_string(half.x()) + ", " + std::to_string(half.y()) + ", " +
                                std::to_string(half.z()) + ")");
  }
  TriangleMesh m;
  for (int k = 0; k < 8; ++k) {
    m.vertices.push_back({(k & 1) ? half.x() : -half.x(), (k & 2) ? half.y() : -half.y(),
                          (k & 4) ? half.z() : -half.z()});
  }
  // Outward, counter-clockwise: -z, +z, -y, +y, -x, +x.
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                           {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) {
    m.triangles.push_back({f[0], f[1], f[2]});
    m.triangles.push_back({f[0], f[2], f[3]});
  }
  return m;
}

}  // namespace pg
