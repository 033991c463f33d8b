#pragma once
// Simple closed meshes for tests, benchmarks and quick scenes (the paper's objects are in meshes/).
#include "pg/sim/mesh.h"

namespace pg {

// Latitude-longitude sphere centred at the origin: 2 * rings * segments triangles. Throws
// std::invalid_argument for a radius that is not positive, fewer than 2 rings or 3 segments.
TriangleMesh make_uv_sphere(float radius_m, int rings, int segments);
// Axis-aligned box centred at the origin with the given half extents [m]: 12 triangles. Throws
// std::invalid_argument for an extent that is not positive.
TriangleMesh make_box(const Eigen::Vector3f& half_extents_m);

}  // namespace pg
