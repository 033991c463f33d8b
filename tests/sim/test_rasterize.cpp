// The rasterizer's culling (sim/src/rasterize.h) against the unculled path: the clusters that
// clusters_in_slab drops, and the triangles that the vertex keys drop, never hold a hit in front
// of the gel. Bit for bit, over seeded poses of the paper's meshes and of tiny-triangle meshes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>

#include "gel_surface.h"
#include "pg/sim/mesh.h"
#include "pg/sim/primitives.h"
#include "rasterize.h"

namespace pg {
namespace {

struct NamedMesh {
  std::string name;
  TriangleMesh mesh;
};

std::vector<NamedMesh> test_meshes() {
  std::vector<NamedMesh> out = {{"box", make_box({0.004f, 0.004f, 0.004f})},
                                {"sphere 200k", make_uv_sphere(0.006f, 250, 400)}};
  for (const char* name : {"toy_brick", "toy_human"}) {
    out.push_back({name, load_mesh(std::string(PG_SOURCE_DIR) + "/meshes/" + name + ".glb")});
  }
  return out;
}

// First hits in front of the undeformed gel (+inf elsewhere) of the given clusters.
std::vector<float> hits_in_front(const TriangleClusters& c, const std::vector<int>& clusters,
                                 const SE3& T_sensor_object, const SensorModel& sensor,
                                 const GelGeometry& gel, float small_triangle_px) {
  std::vector<float> hit_t(gel.t_gel.size(), std::numeric_limits<float>::infinity());
  SlabRaster raster;
  raster.gel = &gel;
  raster.slab_m = float(sensor.gel.max_indentation_m);
  raster.front_faces_only = true;
  raster.small_triangle_px = small_triangle_px;
  raster.rect = {0, 0, gel.width, gel.height};
  raster.hit_t = hit_t.data();
  const CameraModel& cam = sensor.camera;
  rasterize_clusters(c, clusters, T_sensor_object, Eigen::Vector4d(cam.fx, cam.fy, cam.cx, cam.cy),
                     raster);
  for (std::size_t i = 0; i < hit_t.size(); ++i) {
    if (!(hit_t[i] < gel.t_gel[i])) hit_t[i] = std::numeric_limits<float>::infinity();
  }
  return hit_t;
}

// Pixels whose values differ in their bits, and how many hit at all.
struct Comparison {
  int differ = 0, hits = 0;
};
Comparison compare(const std::vector<float>& a, const std::vector<float>& b) {
  Comparison out;
  for (std::size_t i = 0; i < a.size(); ++i) {
    out.differ += std::memcmp(&a[i], &b[i], sizeof(float)) != 0;
    out.hits += std::isfinite(a[i]);
  }
  return out;
}

// A seeded pose that presses the mesh's lowest point `press` into the gel centre's plane,
// turned at random and moved up to 3 mm sideways.
SE3 random_press(const TriangleMesh& mesh, double press, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const SE3 R(quaternion_from_rpy({3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng)}),
              Eigen::Vector3d::Zero());
  double lowest = std::numeric_limits<double>::infinity();
  for (const auto& v : mesh.vertices) lowest = std::min(lowest, (R * v.cast<double>()).z());
  return SE3::Translation({0.003 * u(rng), 0.003 * u(rng), -lowest - press}) * R;
}

TEST(RasterizeCulling, ClustersInTheSlabHoldEveryHitInFrontOfTheGel) {
  std::mt19937 rng(11);
  for (const NamedMesh& m : test_meshes()) {
    const TriangleClusters c = make_clusters(m.mesh);
    std::vector<int> all(c.clusters.size());
    for (std::size_t i = 0; i < all.size(); ++i) all[i] = int(i);
    for (const char* preset : {"digit", "digit_240x320"}) {
      const SensorModel sensor = sensor_preset(preset);
      const GelGeometry gel = make_gel_geometry(sensor);
      long kept = 0, total = 0;
      int hits = 0;
      for (int k = 0; k < 6; ++k) {
        const SE3 pose = random_press(m.mesh, 0.0002 + 0.0003 * k, rng);
        SlabClusters slab;
        clusters_in_slab(c, pose, gel, float(sensor.gel.max_indentation_m), slab);
        const Comparison d = compare(hits_in_front(c, all, pose, sensor, gel, 1.0f),
                                     hits_in_front(c, slab.clusters, pose, sensor, gel, 1.0f));
        EXPECT_EQ(d.differ, 0) << m.name << " " << preset << " pose " << k;
        hits += d.hits;
        kept += long(slab.clusters.size());
        total += long(c.clusters.size());
      }
      EXPECT_GT(hits, 0) << m.name << " " << preset;
      // A big mesh keeps only its clusters near the gel.
      if (c.clusters.size() > 100) {
        EXPECT_LT(kept, total / 5) << m.name << " " << preset;
      }
    }
  }
}

TEST(RasterizeCulling, VertexKeysKeepEveryTriangleThatCoversAPixelCentre) {
  std::mt19937 rng(12);
  for (const NamedMesh& m : test_meshes()) {
    const TriangleClusters c = make_clusters(m.mesh);
    for (const char* preset : {"digit", "digit_240x320"}) {
      const SensorModel sensor = sensor_preset(preset);
      const GelGeometry gel = make_gel_geometry(sensor);
      for (int k = 0; k < 4; ++k) {
        const SE3 pose = random_press(m.mesh, 0.0003 + 0.0004 * k, rng);
        SlabClusters slab;
        clusters_in_slab(c, pose, gel, float(sensor.gel.max_indentation_m), slab);
        // No cluster by keys, the default (tiny triangles by keys), every cluster by keys.
        const std::vector<float> none = hits_in_front(c, slab.clusters, pose, sensor, gel, 0.0f);
        for (float px : {1.0f, 1e9f}) {
          const Comparison d =
              compare(none, hits_in_front(c, slab.clusters, pose, sensor, gel, px));
          EXPECT_EQ(d.differ, 0) << m.name << " " << preset << " pose " << k << " keys below "
                                 << px;
        }
      }
    }
  }
}

// Vertices on and within a hair of pixel centres, where the keys' tolerance flags decide.
TEST(RasterizeCulling, VertexKeysHoldAtPixelCentres) {
  const SensorModel sensor = sensor_preset("digit");
  const GelGeometry gel = make_gel_geometry(sensor);
  const CameraModel& cam = sensor.camera;
  // A grid of half-pixel cells 0.35 to 0.7 mm in front of the gel's centre: every other vertex
  // seen within 3e-5 px of a pixel centre (so that the triangles around it cover it within
  // their edge tolerance), the others nudged by up to twice the boxes' tolerance; bumpy, so that
  // the triangles around a pixel centre disagree on its hit.
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> hair(-3e-5, 3e-5), nudge(-2e-3, 2e-3),
      height(-0.0007, -0.00035);
  TriangleMesh grid;
  const int n = 2 * 40 + 1;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const double u = 40 + 0.5 * i + (i % 2 ? nudge(rng) : hair(rng));
      const double w = 60 + 0.5 * j + (j % 2 ? nudge(rng) : hair(rng));
      const double z = height(rng), depth = z + cam.distance_m;
      grid.vertices.push_back(
          Eigen::Vector3d((u - cam.cx) / cam.fx * depth, (w - cam.cy) / cam.fy * depth, z)
              .cast<float>());
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const int a = j * n + i;
      grid.triangles.push_back({a, a + n, a + 1});
      grid.triangles.push_back({a + 1, a + n, a + n + 1});
    }
  }
  const TriangleClusters c = make_clusters(grid);
  std::vector<int> all(c.clusters.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = int(i);
  const std::vector<float> none = hits_in_front(c, all, SE3(), sensor, gel, 0.0f);
  for (float px : {1.0f, 1e9f}) {
    const Comparison d = compare(none, hits_in_front(c, all, SE3(), sensor, gel, px));
    EXPECT_EQ(d.differ, 0) << "keys below " << px;
    EXPECT_GE(d.hits, 39 * 39) << "keys below " << px;
  }
}

// The gel's radial bound holds for every pixel's gel point: no gel point farther from the axis
// lies higher.
TEST(RasterizeCulling, GelBoundIsAtLeastEveryGelPointFartherOut) {
  for (const char* preset : {"digit", "gelsight_mini"}) {
    const GelGeometry gel = make_gel_geometry(sensor_preset(preset));
    std::vector<std::pair<float, float>> points;  // rho^2, z
    for (std::size_t i = 0; i < gel.t_gel.size(); ++i) {
      const Eigen::Vector3f p = gel.point(int(i), 0.0f);
      points.push_back({p.x() * p.x() + p.y() * p.y(), p.z()});
    }
    std::mt19937 rng(14);
    std::uniform_real_distribution<float> pick(0.0f, 1.2f * gel.rho_sq_step * 255.0f);
    for (int k = 0; k < 200; ++k) {
      const float rho_sq = pick(rng);
      float highest = -std::numeric_limits<float>::infinity();
      for (const auto& [r, z] : points)
        if (r >= rho_sq) highest = std::max(highest, z);
      EXPECT_GE(gel.highest_gel_z_beyond(rho_sq), highest) << preset << " rho^2 " << rho_sq;
    }
  }
}

}  // namespace
}  // namespace pg
