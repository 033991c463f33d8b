#pragma once
// The gel's surface as the camera sees it: per-pixel rays to the undeformed gel and the deformed
// surface's normals (the elastic deformation: pg/core/gel_elastic.h). Free functions over plain
// arrays.
#include <Eigen/Core>
#include <vector>

#include "pg/core/gel_elastic.h"
#include "pg/core/gel_rays.h"
#include "pg/core/pixel_rect.h"
#include "pg/core/sensor.h"

namespace pg {

// Per-sensor constants: one ray per pixel from the camera centre and where it meets the gel
// (GelRays, shared with the tracker), plus the bounds the renderer culls with.
struct GelGeometry : GelRays {
  std::vector<float> dir_x, dir_y;  // the rays' x and y, as plain arrays for vector loops
  float z_gel_min = 0;              // lowest undeformed gel z in view [m]
  // highest_z[b]: the highest undeformed gel point seen by any pixel whose gel point lies at
  // least sqrt(b * rho_sq_step) from the z axis [m] (-inf where there is none).
  std::vector<float> highest_z;
  float rho_sq_step = 0;  // [m^2]

  // An upper bound of z_gel over the pixels whose undeformed gel point lies at least
  // sqrt(rho_sq) from the z axis. A point p in front of the camera that a pixel's ray meets
  // before the undeformed gel lies below this bound at p's own rho_sq: the ray moves away from
  // the axis as z grows, so its gel point is farther out than p, and higher than p.
  float highest_gel_z_beyond(float rho_sq) const {
    const float b = rho_sq / rho_sq_step;
    const int n = int(highest_z.size());
    return highest_z[b < float(n - 1) ? int(b) : n - 1];
  }
};

GelGeometry make_gel_geometry(const SensorModel& sensor);

// Unit normals (pointing +z, out of the gel toward the object) of the surface displaced by u,
// over `rect`, written to normals (3 floats per pixel, image-sized). u is read on rect dilated
// by one pixel (clipped to the image), so it must be valid (or zero) there.
void surface_normals(const GelGeometry& g, const float* u, const PixelRect& rect, float* normals);

}  // namespace pg
