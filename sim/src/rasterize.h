#pragma once
// The fine pass without rays: the triangles near the gel slab, rasterized into per-pixel first
// hits. Exact like ray casting (each pixel's hit comes from its own ray through the triangle's
// plane), and cheaper when few triangles cover many pixels. Internal to pg_sim.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gel_surface.h"
#include "pg/core/se3.h"
#include "pg/sim/mesh.h"
#include "pixel_rect.h"

namespace pg {

// Triangles grouped by Morton order of their centroids, each group bounded by a sphere.
struct TriangleClusters {
  struct Cluster {
    Eigen::Vector3f centre;  // object frame [m]
    float radius = 0;
    int first = 0, count = 0;  // into `order`
  };
  std::vector<int> order;  // triangle indices
  std::vector<Cluster> clusters;
};
TriangleClusters make_clusters(const TriangleMesh& mesh, int per_cluster = 32);

// Clusters that may reach into z in [z_lo, z_hi] of the sensor frame at this pose.
std::vector<int> clusters_in_slab(const TriangleClusters& c, const SE3& T_sensor_object,
                                  float z_lo, float z_hi);
long triangle_count(const TriangleClusters& c, const std::vector<int>& clusters);

// Per-pixel first hit along each pixel's ray, for t >= tnear = t_gel - slab_m, over `rect`.
// hit_t must hold +inf (or an earlier object's hit) on rect; back is set where the kept hit
// faces away from the ray.
struct SlabRaster {
  const GelGeometry* gel = nullptr;
  float slab_m = 0;
  PixelRect rect;
  float* hit_t = nullptr;
  std::uint8_t* back = nullptr;
};
void rasterize_clusters(const TriangleMesh& mesh, const TriangleClusters& c,
                        const std::vector<int>& clusters, const SE3& T_sensor_object,
                        const Eigen::Vector4d& intrinsics /* fx fy cx cy */, SlabRaster& out);

}  // namespace pg
