#pragma once
// Points spread evenly over a mesh's surface, with the faces' outward normals: the known object
// model of the GroundtruthPatch baseline, and reference surfaces for tests.
#include <cstdint>

#include "pg/sim/mesh.h"

namespace pg {

struct SurfaceSamples {
  std::vector<Eigen::Vector3f> points;   // object frame [m]
  std::vector<Eigen::Vector3f> normals;  // unit, outward
};

// Throws std::invalid_argument, naming `what`, unless spacing_m is positive and finite: for the
// samplers here and surface_grid (presses.h), which throw it.
void check_sample_spacing(double spacing_m, const char* what);

// About one point per spacing_m^2 of area (at least one per triangle), placed by a seeded
// stratified scheme: deterministic for a mesh, spacing and seed.
SurfaceSamples sample_surface(const TriangleMesh& mesh, double spacing_m, std::uint64_t seed = 1);

// How many points sample_surface places for `mesh` at `spacing_m` (to within one per triangle),
// without placing them: a caller checks a model's size before asking for it.
double surface_sample_count(const TriangleMesh& mesh, double spacing_m);

}  // namespace pg
