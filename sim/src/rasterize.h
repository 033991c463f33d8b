#pragma once
// The fine pass without rays: the triangles near the gel slab, rasterized into per-pixel first
// hits. Exact like ray casting (each pixel's hit comes from its own ray through the triangle's
// plane), and cheaper when few triangles cover many pixels. Internal to pg_sim.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gel_surface.h"
#include "pg/core/pixel_rect.h"
#include "pg/core/se3.h"
#include "pg/sim/mesh.h"

namespace pg {

// Triangles grouped by Morton order of their centroids, each group (cluster) bounded by a box.
// Each cluster keeps its own copy of its vertices, so that a frame transforms each vertex once
// (a vertex is shared by about six triangles) and reads them from one small block. Consecutive
// clusters are grouped again, kGroupClusters at a time, so that a frame skips most of a big
// mesh's clusters a group at a time.
struct TriangleClusters {
  struct Cluster {
    Eigen::Vector3f centre;                      // of its bounding box, object frame [m]
    Eigen::Vector3f half_extent;                 // of its bounding box [m]
    int first_triangle = 0, triangle_count = 0;  // into corner_a, b, c
    int first_vertex = 0, vertex_count = 0;      // into x, y, z
    float longest_edge = 0;                      // of its triangles [m]
  };
  struct Group {
    Eigen::Vector3f centre, half_extent;  // a box around its clusters' boxes [m]
    int first_cluster = 0, cluster_count = 0;
  };
  static constexpr int kMaxTriangles = 85;  // per cluster, so that 255 vertices index in a byte
  static constexpr int kGroupClusters = 16;
  static constexpr int kVertexBlock = 16;  // x, y, z end with this many zeros of padding
  std::vector<float> x, y, z;              // vertices in the object frame [m], grouped by cluster
  std::vector<std::uint8_t> corner_a, corner_b, corner_c;  // per triangle, into its cluster's
  std::vector<Cluster> clusters;
  std::vector<Group> groups;
};
TriangleClusters make_clusters(const TriangleMesh& mesh, int per_cluster = 32);

// The clusters whose triangles a pixel's ray may meet in front of the undeformed gel at this
// pose, within reach_m of it (from the gel down to reach_m below its lowest point: the slab, or
// +inf for every cluster in front of the gel); their triangle count and bounds; and how low the
// mesh may reach.
struct SlabClusters {
  std::vector<int> clusters;
  long triangles = 0;
  Eigen::Vector3f lo, hi;  // bounds of those clusters' boxes in the sensor frame [m]
  // The lowest z of the clusters' boxes [m]; where that lies above the gel's top (z = 0) or
  // below the reach, possibly a lower value on the same side.
  float lowest_z = 0;
  float reach_m = 0;
};
void clusters_in_slab(const TriangleClusters& c, const SE3& T_sensor_object, const GelGeometry& gel,
                      float reach_m, SlabClusters& out);

// Per-pixel first hit along each pixel's ray, for t >= tnear = t_gel - slab_m, over `rect`.
// hit_t must hold +inf (or an earlier object's hit) on rect. `touched` grows to cover every pixel
// written. Used only where no pixel's ray starts inside the object within the slab, or with
// every cluster in front of the gel and slab_m = +inf (each ray then starts at the camera, which
// is outside the object): so on a closed mesh (`front_faces_only`) the first face a ray meets
// faces the camera, and the faces turned away are skipped (one can come first only by a
// rounding error where a ray grazes the object's outline, and it would count as the ray
// starting inside). A hit is kept within its triangle's depth range: a pixel centre that the
// edges' tolerance takes in just outside a triangle seen nearly edge-on would otherwise read its
// plane far beyond the triangle.
struct SlabRaster {
  const GelGeometry* gel = nullptr;
  float slab_m = 0;
  bool front_faces_only = false;
  // Clusters whose triangles are all shorter than this (at the gel's centre) [px] are culled
  // by vertex keys, in batches (rasterize.cpp); the same result, cheaper for tiny triangles.
  float small_triangle_px = 1.0f;
  PixelRect rect;
  float* hit_t = nullptr;
  PixelRect touched;
};
void rasterize_clusters(const TriangleClusters& c, const std::vector<int>& clusters,
                        const SE3& T_sensor_object,
                        const Eigen::Vector4d& intrinsics /* fx fy cx cy */, SlabRaster& out);

}  // namespace pg
