#include "rasterize.h"

#include <algorithm>
#include <cmath>

namespace pg {

namespace {

// Spreads the low 10 bits of v so that two zero bits separate each.
std::uint32_t spread_bits(std::uint32_t v) {
  v &= 0x3FF;
  v = (v | (v << 16)) & 0x030000FF;
  v = (v | (v << 8)) & 0x0300F00F;
  v = (v | (v << 4)) & 0x030C30C3;
  v = (v | (v << 2)) & 0x09249249;
  return v;
}

}  // namespace

TriangleClusters make_clusters(const TriangleMesh& mesh, int per_cluster) {
  TriangleClusters out;
  const Bounds3 b = mesh_bounds(mesh);
  const Eigen::Vector3f extent = (b.max - b.min).cwiseMax(1e-12f);
  std::vector<std::pair<std::uint32_t, int>> keyed;
  keyed.reserve(mesh.triangles.size());
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    const Eigen::Vector3f c = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3;
    const Eigen::Vector3f q = ((c - b.min).cwiseQuotient(extent) * 1023.0f).cwiseMax(0).cwiseMin(1023);
    const std::uint32_t key = spread_bits(std::uint32_t(q.x())) |
                              (spread_bits(std::uint32_t(q.y())) << 1) |
                              (spread_bits(std::uint32_t(q.z())) << 2);
    keyed.push_back({key, int(i)});
  }
  std::sort(keyed.begin(), keyed.end());
  for (const auto& k : keyed) out.order.push_back(k.second);
  for (int first = 0; first < int(out.order.size()); first += per_cluster) {
    TriangleClusters::Cluster cl;
    cl.first = first;
    cl.count = std::min(per_cluster, int(out.order.size()) - first);
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
    for (int k = 0; k < cl.count; ++k) {
      for (int v : {0, 1, 2}) {
        const auto& p = mesh.vertices[mesh.triangles[out.order[first + k]][v]];
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
    }
    cl.centre = 0.5f * (lo + hi);
    cl.radius = 0.5f * (hi - lo).norm();
    out.clusters.push_back(cl);
  }
  return out;
}

std::vector<int> clusters_in_slab(const TriangleClusters& c, const SE3& T_sensor_object,
                                  float z_lo, float z_hi) {
  const Eigen::Matrix3d R = T_sensor_object.rotation_matrix();
  const Eigen::Vector3f r_z = R.row(2).cast<float>();
  const float t_z = float(T_sensor_object.translation().z());
  std::vector<int> out;
  for (int i = 0; i < int(c.clusters.size()); ++i) {
    const auto& cl = c.clusters[i];
    const float z = r_z.dot(cl.centre) + t_z;
    if (z - cl.radius <= z_hi && z + cl.radius >= z_lo) out.push_back(i);
  }
  return out;
}

long triangle_count(const TriangleClusters& c, const std::vector<int>& clusters) {
  long n = 0;
  for (int i : clusters) n += c.clusters[i].count;
  return n;
}

void rasterize_clusters(const TriangleMesh& mesh, const TriangleClusters& c,
                        const std::vector<int>& clusters, const SE3& T_sensor_object,
                        const Eigen::Vector4d& k, SlabRaster& out) {
  const GelGeometry& g = *out.gel;
  const Eigen::Matrix3f R = T_sensor_object.rotation_matrix().cast<float>();
  const Eigen::Vector3f t = T_sensor_object.translation().cast<float>();
  const Eigen::Vector3f o = g.origin_sensor;
  const float fx = float(k[0]), fy = float(k[1]), cx = float(k[2]), cy = float(k[3]);
  const float z_top = 0.0f;  // the highest undeformed gel point
  const float z_bottom = g.z_gel_min - out.slab_m;
  const PixelRect& rect = out.rect;
  for (int ci : clusters) {
    const auto& cl = c.clusters[ci];
    for (int k_tri = 0; k_tri < cl.count; ++k_tri) {
      const auto& tri = mesh.triangles[c.order[cl.first + k_tri]];
      Eigen::Vector3f p[3];
      for (int v = 0; v < 3; ++v) p[v] = R * mesh.vertices[tri[v]] + t;
      const float z_min = std::min({p[0].z(), p[1].z(), p[2].z()});
      const float z_max = std::max({p[0].z(), p[1].z(), p[2].z()});
      if (z_min > z_top || z_max < z_bottom) continue;  // cannot meet a pixel's slab
      // Pixel coordinates of the vertices (pixel centres at integers).
      float u[3], w[3];
      for (int v = 0; v < 3; ++v) {
        const Eigen::Vector3f q = p[v] - o;
        u[v] = fx * q.x() / q.z() + cx;
        w[v] = fy * q.y() / q.z() + cy;
      }
      const float area = (u[1] - u[0]) * (w[2] - w[0]) - (u[2] - u[0]) * (w[1] - w[0]);
      if (std::abs(area) < 1e-12f) continue;  // seen edge-on: no pixel's ray meets it
      const PixelRect box = PixelRect{int(std::ceil(std::min({u[0], u[1], u[2]}) - 1e-3f)),
                                      int(std::ceil(std::min({w[0], w[1], w[2]}) - 1e-3f)),
                                      int(std::floor(std::max({u[0], u[1], u[2]}) + 1e-3f)) + 1,
                                      int(std::floor(std::max({w[0], w[1], w[2]}) + 1e-3f)) + 1}
                                .clipped(rect.x1, rect.y1);
      if (box.empty()) continue;
      const int x_start = std::max(box.x0, rect.x0), y_start = std::max(box.y0, rect.y0);
      const Eigen::Vector3f n = (p[1] - p[0]).cross(p[2] - p[0]);
      const float n_dot_p0 = n.dot(p[0] - o);
      // Edge functions, scaled by the sign of the area so that inside is >= 0; a small
      // tolerance makes neighbouring triangles overlap by a hair instead of leaving cracks.
      const float s = area > 0 ? 1.0f : -1.0f;
      const float eps = -1e-4f * std::abs(area);
      for (int y = y_start; y < box.y1; ++y) {
        for (int x = x_start; x < box.x1; ++x) {
          const float e0 = s * ((u[2] - u[1]) * (float(y) - w[1]) - (w[2] - w[1]) * (float(x) - u[1]));
          const float e1 = s * ((u[0] - u[2]) * (float(y) - w[2]) - (w[0] - w[2]) * (float(x) - u[2]));
          const float e2 = s * ((u[1] - u[0]) * (float(y) - w[0]) - (w[1] - w[0]) * (float(x) - u[0]));
          if (e0 < eps || e1 < eps || e2 < eps) continue;
          const int i = g.index(x, y);
          const Eigen::Vector3f& d = g.dir_sensor[i];
          const float n_dot_d = n.dot(d);
          if (n_dot_d == 0.0f) continue;
          const float t_hit = n_dot_p0 / n_dot_d;
          if (t_hit < g.t_gel[i] - out.slab_m || t_hit >= out.hit_t[i]) continue;
          out.hit_t[i] = t_hit;
          out.back[i] = n_dot_d > 0.0f;
        }
      }
    }
  }
}

}  // namespace pg
