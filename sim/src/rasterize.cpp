#include "rasterize.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_map>

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

// Triangle indices in Morton order of their centroids.
std::vector<int> morton_order(const TriangleMesh& mesh) {
  const Bounds3 b = mesh_bounds(mesh);
  const Eigen::Vector3f extent = (b.max - b.min).cwiseMax(1e-12f);
  std::vector<std::pair<std::uint32_t, int>> keyed;
  keyed.reserve(mesh.triangles.size());
  for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& t = mesh.triangles[i];
    const Eigen::Vector3f c = (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3;
    const Eigen::Vector3f q =
        ((c - b.min).cwiseQuotient(extent) * 1023.0f).cwiseMax(0).cwiseMin(1023);
    const std::uint32_t key = spread_bits(std::uint32_t(q.x())) |
                              (spread_bits(std::uint32_t(q.y())) << 1) |
                              (spread_bits(std::uint32_t(q.z())) << 2);
    keyed.push_back({key, int(i)});
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int> order;
  order.reserve(keyed.size());
  for (const auto& k : keyed) order.push_back(k.second);
  return order;
}

}  // namespace

TriangleClusters make_clusters(const TriangleMesh& mesh, int per_cluster) {
  TriangleClusters out;
  const std::vector<int> order = morton_order(mesh);
  per_cluster = std::min(per_cluster, TriangleClusters::kMaxTriangles);
  std::unordered_map<int, int> local;
  for (int first = 0; first < int(order.size()); first += per_cluster) {
    TriangleClusters::Cluster cl;
    cl.first_triangle = int(out.corner_a.size());
    cl.triangle_count = std::min(per_cluster, int(order.size()) - first);
    cl.first_vertex = int(out.x.size());
    local.clear();
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
    for (int k = 0; k < cl.triangle_count; ++k) {
      std::uint8_t corner[3];
      for (int v = 0; v < 3; ++v) {
        const int vertex = mesh.triangles[order[first + k]][v];
        auto [it, added] = local.emplace(vertex, int(out.x.size()) - cl.first_vertex);
        const Eigen::Vector3f& p = mesh.vertices[vertex];
        if (added) {
          out.x.push_back(p.x());
          out.y.push_back(p.y());
          out.z.push_back(p.z());
        }
        corner[v] = std::uint8_t(it->second);
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      out.corner_a.push_back(corner[0]);
      out.corner_b.push_back(corner[1]);
      out.corner_c.push_back(corner[2]);
    }
    cl.vertex_count = int(out.x.size()) - cl.first_vertex;
    cl.centre = 0.5f * (lo + hi);
    cl.half_extent = 0.5f * (hi - lo);
    out.clusters.push_back(cl);
  }
  return out;
}

void clusters_in_slab(const TriangleClusters& c, const SE3& T_sensor_object, float z_lo, float z_hi,
                      SlabClusters& out) {
  const Eigen::Matrix3f R = T_sensor_object.rotation_matrix().cast<float>();
  const Eigen::Matrix3f R_abs = R.cwiseAbs();
  const Eigen::Vector3f t = T_sensor_object.translation().cast<float>();
  const Eigen::Vector3f r_z = R.row(2), r_z_abs = R_abs.row(2);
  out.clusters.clear();
  out.triangles = 0;
  out.lo = Eigen::Vector3f::Constant(INFINITY);
  out.hi = -out.lo;
  out.lowest_z = INFINITY;
  for (int i = 0; i < int(c.clusters.size()); ++i) {
    const auto& cl = c.clusters[i];
    // A box's extent along a direction r: |r| . half extent.
    const float z = r_z.dot(cl.centre) + t.z(), dz = r_z_abs.dot(cl.half_extent);
    out.lowest_z = std::min(out.lowest_z, z - dz);
    if (z - dz <= z_hi && z + dz >= z_lo) {
      out.clusters.push_back(i);
      out.triangles += cl.triangle_count;
      const Eigen::Vector3f centre = R * cl.centre + t, extent = R_abs * cl.half_extent;
      out.lo = out.lo.cwiseMin(centre - extent);
      out.hi = out.hi.cwiseMax(centre + extent);
    }
  }
}

namespace {

// One cluster's vertices in the sensor frame (p) and in pixel coordinates (u, w; pixel centres
// at integers), and the triangles that may cover a pixel centre of the rectangle with their
// pixel bounding boxes.
struct ClusterInView {
  static constexpr int kVertices = 3 * TriangleClusters::kMaxTriangles;
  float px[kVertices], py[kVertices], pz[kVertices], u[kVertices], w[kVertices];
  int count = 0;  // candidate triangles
  int triangle[TriangleClusters::kMaxTriangles];
  PixelRect box[TriangleClusters::kMaxTriangles];
};

struct View {
  Eigen::Matrix3f R;
  Eigen::Vector3f t, o;  // translation, camera centre
  float fx, fy, cx, cy;
};

// Vertices into the sensor frame and onto the image; a vector loop.
__attribute__((noinline)) void transform_vertices(int n, const float* __restrict x,
                                                  const float* __restrict y,
                                                  const float* __restrict z, const View& v,
                                                  ClusterInView& out) {
  const float r00 = v.R(0, 0), r01 = v.R(0, 1), r02 = v.R(0, 2), tx = v.t.x();
  const float r10 = v.R(1, 0), r11 = v.R(1, 1), r12 = v.R(1, 2), ty = v.t.y();
  const float r20 = v.R(2, 0), r21 = v.R(2, 1), r22 = v.R(2, 2), tz = v.t.z();
  const float ox = v.o.x(), oy = v.o.y(), oz = v.o.z();
  const float fx = v.fx, fy = v.fy, cx = v.cx, cy = v.cy;
  float* __restrict out_x = out.px;
  float* __restrict out_y = out.py;
  float* __restrict out_z = out.pz;
  float* __restrict out_u = out.u;
  float* __restrict out_w = out.w;
  for (int j = 0; j < n; ++j) {
    const float px = r00 * x[j] + r01 * y[j] + r02 * z[j] + tx;
    const float py = r10 * x[j] + r11 * y[j] + r12 * z[j] + ty;
    const float pz = r20 * x[j] + r21 * y[j] + r22 * z[j] + tz;
    out_x[j] = px;
    out_y[j] = py;
    out_z[j] = pz;
    const float qz = pz - oz;
    out_u[j] = fx * (px - ox) / qz + cx;
    out_w[j] = fy * (py - oy) / qz + cy;
  }
}

// Per triangle k of a cluster: whether it reaches into z in [z_lo, z_hi] and its bounding box
// holds a pixel centre of `rect` (keep[k]), and that box. When the box holds a single centre,
// as it mostly does for triangles smaller than a pixel, keep[k] also says whether the triangle
// covers it (the same test as rasterize_triangle's). A vector loop (gathers through the corner
// indices); not inlined, as GCC 12 drops restrict qualifiers when inlining.
__attribute__((noinline)) void triangle_boxes(
    int n, const std::uint8_t* __restrict ca, const std::uint8_t* __restrict cb,
    const std::uint8_t* __restrict cc, const float* __restrict pz, const float* __restrict u,
    const float* __restrict w, float z_lo, float z_hi, const PixelRect& rect, int* __restrict keep,
    int* __restrict bx0, int* __restrict by0, int* __restrict bx1, int* __restrict by1) {
  const int rx0 = rect.x0, ry0 = rect.y0, rx1 = rect.x1, ry1 = rect.y1;
  for (int k = 0; k < n; ++k) {
    const int a = ca[k], b = cb[k], d = cc[k];
    const float z_min = std::min(std::min(pz[a], pz[b]), pz[d]);
    const float z_max = std::max(std::max(pz[a], pz[b]), pz[d]);
    // Pixel centres within the bounding box, with a hair of tolerance.
    const int x0 = std::max(int(std::ceil(std::min(std::min(u[a], u[b]), u[d]) - 1e-3f)), rx0);
    const int y0 = std::max(int(std::ceil(std::min(std::min(w[a], w[b]), w[d]) - 1e-3f)), ry0);
    const int x1 = std::min(int(std::floor(std::max(std::max(u[a], u[b]), u[d]) + 1e-3f)) + 1, rx1);
    const int y1 = std::min(int(std::floor(std::max(std::max(w[a], w[b]), w[d]) + 1e-3f)) + 1, ry1);
    // Edge functions at the box's first centre, as in rasterize_triangle.
    const float area = (u[b] - u[a]) * (w[d] - w[a]) - (u[d] - u[a]) * (w[b] - w[a]);
    const float s = area > 0 ? 1.0f : -1.0f;
    const float eps = -1e-4f * std::abs(area);
    const float fx = float(x0), fy = float(y0);
    const float e0 = s * ((u[d] - u[b]) * (fy - w[b]) - (w[d] - w[b]) * (fx - u[b]));
    const float e1 = s * ((u[a] - u[d]) * (fy - w[d]) - (w[a] - w[d]) * (fx - u[d]));
    const float e2 = s * ((u[b] - u[a]) * (fy - w[a]) - (w[b] - w[a]) * (fx - u[a]));
    const bool single = (x1 - x0 == 1) & (y1 - y0 == 1);
    const bool covers = (e0 >= eps) & (e1 >= eps) & (e2 >= eps);
    keep[k] = (z_min <= z_hi) & (z_max >= z_lo) & (x0 < x1) & (y0 < y1) &
              (std::abs(area) >= 1e-12f) & (!single | covers);
    bx0[k] = x0;
    by0[k] = y0;
    bx1[k] = x1;
    by1[k] = y1;
  }
}

// The cluster's triangles that reach into z in [z_lo, z_hi] and whose bounding box holds a
// pixel centre of `rect`, listed without branches: for triangles smaller than a pixel that is
// a coin toss, which a branch would mostly mispredict.
void candidate_triangles(const TriangleClusters& c, const TriangleClusters::Cluster& cl, float z_lo,
                         float z_hi, const PixelRect& rect, ClusterInView& v) {
  constexpr int kMax = TriangleClusters::kMaxTriangles;
  int keep[kMax], x0[kMax], y0[kMax], x1[kMax], y1[kMax];
  const std::size_t f = std::size_t(cl.first_triangle);
  triangle_boxes(cl.triangle_count, &c.corner_a[f], &c.corner_b[f], &c.corner_c[f], v.pz, v.u, v.w,
                 z_lo, z_hi, rect, keep, x0, y0, x1, y1);
  int count = 0;
  for (int k = 0; k < cl.triangle_count; ++k) {
    v.triangle[count] = k;
    v.box[count] = {x0[k], y0[k], x1[k], y1[k]};
    count += keep[k];
  }
  v.count = count;
}

// A triangle ready to draw: its corners in pixel coordinates, edge-function sign and tolerance,
// and its plane (a pixel's ray with direction d meets it at t = n_dot_p0 / (n . d)).
struct TriangleSetup {
  float u[3], w[3];
  float s, eps;
  float nx, ny, nz, n_dot_p0;
};

// c ? a : b by bit masks: a scalar compiler makes a branch of `?:` here, and a mispredicted one.
inline float select(bool c, float a, float b) {
  std::uint32_t ia, ib;
  std::memcpy(&ia, &a, sizeof(ia));
  std::memcpy(&ib, &b, sizeof(ib));
  const std::uint32_t mask = 0u - std::uint32_t(c);
  const std::uint32_t r = (ia & mask) | (ib & ~mask);
  float out;
  std::memcpy(&out, &r, sizeof(out));
  return out;
}

// Pixels [x0, x1) of row fy into the raster: keeps a pixel's first hit in the slab. The edge
// functions are scaled by the sign of the area so that inside is >= 0; their small tolerance
// makes neighbouring triangles overlap by a hair instead of leaving cracks. Branch-free:
// whether a pixel centre is inside a small triangle is a coin toss. The arrays start at the
// row's first pixel.
inline void rasterize_span(const TriangleSetup& t, int x0, int x1, float fy, float slab,
                           const float* __restrict dir_x, const float* __restrict dir_y,
                           const float* __restrict t_gel, float* __restrict hit_t) {
  const float u0 = t.u[0], u1 = t.u[1], u2 = t.u[2], w0 = t.w[0], w1 = t.w[1], w2 = t.w[2];
  const float s = t.s, eps = t.eps, nx = t.nx, ny = t.ny, nz = t.nz, n_dot_p0 = t.n_dot_p0;
  for (int x = x0; x < x1; ++x) {
    const float fx = float(x);
    const float e0 = s * ((u2 - u1) * (fy - w1) - (w2 - w1) * (fx - u1));
    const float e1 = s * ((u0 - u2) * (fy - w2) - (w0 - w2) * (fx - u2));
    const float e2 = s * ((u1 - u0) * (fy - w0) - (w1 - w0) * (fx - u0));
    const float n_dot_d = nx * dir_x[x] + ny * dir_y[x] + nz;
    // Seen edge-on (n_dot_d = 0) the hit is +-inf or NaN, which the tests below reject.
    const float t_hit = n_dot_p0 / n_dot_d;
    const bool covers = (e0 >= eps) & (e1 >= eps) & (e2 >= eps) & (t_hit >= t_gel[x] - slab);
    const bool hit = covers & (t_hit < hit_t[x]);
    hit_t[x] = select(hit, t_hit, hit_t[x]);
  }
}

// The same as a vector loop, for long rows (not inlined: GCC 12 drops restrict when inlining).
__attribute__((noinline)) void rasterize_long_span(const TriangleSetup& t, int x0, int x1, float fy,
                                                   float slab, const float* __restrict dir_x,
                                                   const float* __restrict dir_y,
                                                   const float* __restrict t_gel,
                                                   float* __restrict hit_t) {
  rasterize_span(t, x0, x1, fy, slab, dir_x, dir_y, t_gel, hit_t);
}

// A triangle whose box holds at most 4 x 4 pixel centres, as one 16-lane computation that the
// compiler vectorises: no loop bounds or branches to mispredict. Lanes beyond the box read the
// box's last row or column and are written first (k descending), so the lane that owns the
// pixel writes last.
void rasterize_small(const TriangleSetup& t, const PixelRect& box, const GelGeometry& g, float slab,
                     float* hit_t) {
  constexpr int kLanes = 16;
  alignas(64) float fx[kLanes], fy[kLanes], dir_x[kLanes], dir_y[kLanes], t_gel[kLanes];
  alignas(64) float old_t[kLanes], new_t[kLanes];
  alignas(64) int index[kLanes];
  for (int k = 0; k < kLanes; ++k) {
    const int x = box.x0 + (k & 3), y = box.y0 + (k >> 2);
    const int i = g.index(std::min(x, box.x1 - 1), std::min(y, box.y1 - 1));
    index[k] = i;
    fx[k] = float(x);
    fy[k] = float(y);
    dir_x[k] = g.dir_x[i];
    dir_y[k] = g.dir_y[i];
    t_gel[k] = g.t_gel[i];
    old_t[k] = hit_t[i];
  }
  const float u0 = t.u[0], u1 = t.u[1], u2 = t.u[2], w0 = t.w[0], w1 = t.w[1], w2 = t.w[2];
  const int x1 = box.x1, y1 = box.y1;
  for (int k = 0; k < kLanes; ++k) {
    // The same arithmetic as rasterize_span.
    const float e0 = t.s * ((u2 - u1) * (fy[k] - w1) - (w2 - w1) * (fx[k] - u1));
    const float e1 = t.s * ((u0 - u2) * (fy[k] - w2) - (w0 - w2) * (fx[k] - u2));
    const float e2 = t.s * ((u1 - u0) * (fy[k] - w0) - (w1 - w0) * (fx[k] - u0));
    const float n_dot_d = t.nx * dir_x[k] + t.ny * dir_y[k] + t.nz;
    const float t_hit = t.n_dot_p0 / n_dot_d;
    const bool inside = (fx[k] < float(x1)) & (fy[k] < float(y1));
    const bool h = inside & (e0 >= t.eps) & (e1 >= t.eps) & (e2 >= t.eps) &
                   (t_hit >= t_gel[k] - slab) & (t_hit < old_t[k]);
    new_t[k] = h ? t_hit : old_t[k];
  }
  for (int k = kLanes - 1; k >= 0; --k) hit_t[index[k]] = new_t[k];
}

// One triangle (corners a, b, d of the cluster) into the raster, over the pixel centres of box.
void rasterize_triangle(const ClusterInView& v, int a, int b, int d, const PixelRect& box,
                        const Eigen::Vector3f& o, SlabRaster& out) {
  TriangleSetup t = {{v.u[a], v.u[b], v.u[d]}, {v.w[a], v.w[b], v.w[d]}, 0, 0, 0, 0, 0, 0};
  const float area = (t.u[1] - t.u[0]) * (t.w[2] - t.w[0]) - (t.u[2] - t.u[0]) * (t.w[1] - t.w[0]);
  if (std::abs(area) < 1e-12f) return;  // seen edge-on: no pixel's ray meets it
  const Eigen::Vector3f p0(v.px[a], v.py[a], v.pz[a]), p1(v.px[b], v.py[b], v.pz[b]),
      p2(v.px[d], v.py[d], v.pz[d]);
  const Eigen::Vector3f n = (p1 - p0).cross(p2 - p0);
  t.n_dot_p0 = n.dot(p0 - o);
  // A hit at t > 0 has n . d of the sign of n . (p0 - o): positive for a face turned away.
  if (out.front_faces_only && !(t.n_dot_p0 < 0.0f)) return;
  out.touched = out.touched.united(box);
  t.s = area > 0 ? 1.0f : -1.0f;
  t.eps = -1e-4f * std::abs(area);
  t.nx = n.x(), t.ny = n.y(), t.nz = n.z();
  const GelGeometry& g = *out.gel;
  if (box.width() <= 4 && box.height() <= 4 && box.area() > 2) {
    rasterize_small(t, box, g, out.slab_m, out.hit_t);
    return;
  }
  const bool long_rows = box.width() >= 16;
  for (int y = box.y0; y < box.y1; ++y) {
    const int row = g.index(0, y);
    const float *dx = g.dir_x.data() + row, *dy = g.dir_y.data() + row, *tg = g.t_gel.data() + row;
    if (long_rows) {
      rasterize_long_span(t, box.x0, box.x1, float(y), out.slab_m, dx, dy, tg, out.hit_t + row);
    } else {
      rasterize_span(t, box.x0, box.x1, float(y), out.slab_m, dx, dy, tg, out.hit_t + row);
    }
  }
}

}  // namespace

void rasterize_clusters(const TriangleClusters& c, const std::vector<int>& clusters,
                        const SE3& T_sensor_object, const Eigen::Vector4d& k, SlabRaster& out) {
  const GelGeometry& g = *out.gel;
  View view;
  view.R = T_sensor_object.rotation_matrix().cast<float>();
  view.t = T_sensor_object.translation().cast<float>();
  view.o = g.origin_sensor;
  view.fx = float(k[0]), view.fy = float(k[1]), view.cx = float(k[2]), view.cy = float(k[3]);
  // Triangles outside the slab below the highest undeformed gel point cannot meet a pixel's.
  const float z_top = 0.0f, z_bottom = g.z_gel_min - out.slab_m;
  ClusterInView v;
  for (int ci : clusters) {
    const auto& cl = c.clusters[ci];
    transform_vertices(cl.vertex_count, c.x.data() + cl.first_vertex, c.y.data() + cl.first_vertex,
                       c.z.data() + cl.first_vertex, view, v);
    candidate_triangles(c, cl, z_bottom, z_top, out.rect, v);
    for (int j = 0; j < v.count; ++j) {
      const int tri = cl.first_triangle + v.triangle[j];
      rasterize_triangle(v, c.corner_a[tri], c.corner_b[tri], c.corner_c[tri], v.box[j], view.o,
                         out);
    }
  }
}

}  // namespace pg
