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
        const Eigen::Vector3f& q = mesh.vertices[mesh.triangles[order[first + k]][(v + 1) % 3]];
        cl.longest_edge = std::max(cl.longest_edge, (q - p).norm());
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
  for (int first = 0; first < int(out.clusters.size()); first += TriangleClusters::kGroupClusters) {
    TriangleClusters::Group group;
    group.first_cluster = first;
    group.cluster_count =
        std::min(TriangleClusters::kGroupClusters, int(out.clusters.size()) - first);
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
    for (int i = first; i < first + group.cluster_count; ++i) {
      const auto& cl = out.clusters[i];
      lo = lo.cwiseMin(cl.centre - cl.half_extent);
      hi = hi.cwiseMax(cl.centre + cl.half_extent);
    }
    group.centre = 0.5f * (lo + hi);
    // A hair larger, so that rounding leaves every cluster's box inside at any pose.
    group.half_extent = 0.5f * (hi - lo) * (1.0f + 1e-5f) + Eigen::Vector3f::Constant(1e-7f);
    out.groups.push_back(group);
  }
  // Vector loops over a cluster's vertices run in whole blocks, past its end.
  out.x.resize(out.x.size() + TriangleClusters::kVertexBlock, 0.0f);
  out.y.resize(out.y.size() + TriangleClusters::kVertexBlock, 0.0f);
  out.z.resize(out.z.size() + TriangleClusters::kVertexBlock, 0.0f);
  return out;
}

void clusters_in_slab(const TriangleClusters& c, const SE3& T_sensor_object, const GelGeometry& gel,
                      float reach_m, SlabClusters& out) {
  // The flat slab first: the gel's highest point is the origin of S.
  const float z_lo = gel.z_gel_min - reach_m, z_hi = 0.0f;
  // Well above float rounding in the vertices, t_gel and a ray's hit (nanometres), and far below
  // a cluster's size.
  constexpr float kMargin = 1e-5f;  // [m]
  const Eigen::Matrix3f R = T_sensor_object.rotation_matrix().cast<float>();
  const Eigen::Matrix3f R_abs = R.cwiseAbs();
  const Eigen::Vector3f t = T_sensor_object.translation().cast<float>();
  const Eigen::Vector3f r_z = R.row(2), r_z_abs = R_abs.row(2);
  out.clusters.clear();
  out.triangles = 0;
  out.lo = Eigen::Vector3f::Constant(INFINITY);
  out.hi = -out.lo;
  out.lowest_z = INFINITY;
  out.reach_m = reach_m;
  // A box's extent along a direction r: |r| . half extent. A group wholly above the gel's top or
  // below the slab holds no cluster in the slab, and its lowest point bounds theirs.
  for (const auto& group : c.groups) {
    const float gz = r_z.dot(group.centre) + t.z(), gdz = r_z_abs.dot(group.half_extent);
    if (gz - gdz > z_hi || gz + gdz < z_lo) {
      out.lowest_z = std::min(out.lowest_z, gz - gdz);
      continue;
    }
    for (int i = group.first_cluster; i < group.first_cluster + group.cluster_count; ++i) {
      const auto& cl = c.clusters[i];
      const float z = r_z.dot(cl.centre) + t.z(), dz = r_z_abs.dot(cl.half_extent);
      out.lowest_z = std::min(out.lowest_z, z - dz);
      if (z - dz > z_hi || z + dz < z_lo) continue;
      const Eigen::Vector3f centre = R * cl.centre + t, extent = R_abs * cl.half_extent;
      const Eigen::Vector3f lo = centre - extent, hi = centre + extent;
      // A pixel's ray can meet the box in front of the undeformed gel only at a point below the
      // gel's highest point beyond that point's distance from the axis (GelGeometry): test the
      // box's lowest point against the bound at the box's nearest distance from the axis.
      const float dx = std::max(std::max(lo.x(), -hi.x()), 0.0f);
      const float dy = std::max(std::max(lo.y(), -hi.y()), 0.0f);
      if (lo.z() >= gel.highest_gel_z_beyond(dx * dx + dy * dy) + kMargin) continue;
      out.clusters.push_back(i);
      out.triangles += cl.triangle_count;
      out.lo = out.lo.cwiseMin(lo);
      out.hi = out.hi.cwiseMax(hi);
    }
  }
}

namespace {

// Vertices in the sensor frame (p) and in pixel coordinates (u, w; pixel centres at integers),
// of one cluster or of a batch of clusters of small triangles; and the candidate triangles,
// those that may cover a pixel centre of the rectangle, with their corners (indices into the
// vertices) and pixel bounding boxes.
struct ClusterInView {
  static constexpr int kBlock = TriangleClusters::kVertexBlock;
  static constexpr int kVertices = 1024;   // of a batch; a cluster has at most 255
  static constexpr int kCandidates = 512;  // of a batch; a cluster has kMaxTriangles
  // Vector loops write whole blocks, up to a block past the last vertex.
  float px[kVertices + kBlock], py[kVertices + kBlock], pz[kVertices + kBlock];
  float u[kVertices + kBlock], w[kVertices + kBlock];
  std::uint32_t key[kVertices + kBlock];  // see vertex_key
  int count = 0;                          // candidate triangles
  int a[kCandidates], b[kCandidates], d[kCandidates];
  PixelRect box[kCandidates];
};

struct View {
  Eigen::Matrix3f R;
  Eigen::Vector3f t, o;  // translation, camera centre
  float fx, fy, cx, cy;
};

// The tolerance of a triangle's pixel bounding box [px].
constexpr float kBoxTolerance = 1e-3f;

// For clusters of triangles smaller than a pixel, most of whose boxes hold no pixel centre: a
// vertex's key, the pixel column and row at or before it (15 bits each, the top bit of each
// half set when a pixel centre's column or row lies within the boxes' tolerance of it). A
// triangle's box can hold a pixel centre only if its corners' keys differ in both halves, or
// one of them has a flag: three loads and a few integer operations per triangle, instead of
// triangle_box's nine loads and its arithmetic.
inline std::uint32_t vertex_key(float u, float w) {
  const float tol = kBoxTolerance;
  // Corners that all lie between the same two columns of centres, each farther than the
  // tolerance from both, leave the box without a column of centres.
  const float fu = std::floor(u + tol), fw = std::floor(w + tol);
  const bool near_u = !(std::ceil(u - tol) == fu + 1.0f);  // also for NaN
  const bool near_w = !(std::ceil(w - tol) == fw + 1.0f);
  // Clamped to 15 bits (NaN to the low end, and flagged): far outside any image.
  const float cu = fu > -16384.0f ? (fu < 16383.0f ? fu : 16383.0f) : -16384.0f;
  const float cw = fw > -16384.0f ? (fw < 16383.0f ? fw : 16383.0f) : -16384.0f;
  return (std::uint32_t(int(cu) & 0x7FFF) << 16) | std::uint32_t(int(cw) & 0x7FFF) |
         (near_u ? 0x80000000u : 0u) | (near_w ? 0x8000u : 0u);
}

// Vertices x, y, z [0, n) into the sensor frame and onto the image at out's [first, first + n)
// (with kKeys, also their vertex_key), in whole blocks; a vector loop.
template <bool kKeys>
__attribute__((noinline)) void transform_vertices(int n, const float* __restrict x,
                                                  const float* __restrict y,
                                                  const float* __restrict z, const View& v,
                                                  ClusterInView& out, int first = 0) {
  const float r00 = v.R(0, 0), r01 = v.R(0, 1), r02 = v.R(0, 2), tx = v.t.x();
  const float r10 = v.R(1, 0), r11 = v.R(1, 1), r12 = v.R(1, 2), ty = v.t.y();
  const float r20 = v.R(2, 0), r21 = v.R(2, 1), r22 = v.R(2, 2), tz = v.t.z();
  const float ox = v.o.x(), oy = v.o.y(), oz = v.o.z();
  const float fx = v.fx, fy = v.fy, cx = v.cx, cy = v.cy;
  float* __restrict out_x = out.px + first;
  float* __restrict out_y = out.py + first;
  float* __restrict out_z = out.pz + first;
  float* __restrict out_u = out.u + first;
  float* __restrict out_w = out.w + first;
  std::uint32_t* __restrict out_key = out.key + first;
  const int end = (n + ClusterInView::kBlock - 1) / ClusterInView::kBlock * ClusterInView::kBlock;
  for (int j = 0; j < end; ++j) {
    const float px = r00 * x[j] + r01 * y[j] + r02 * z[j] + tx;
    const float py = r10 * x[j] + r11 * y[j] + r12 * z[j] + ty;
    const float pz = r20 * x[j] + r21 * y[j] + r22 * z[j] + tz;
    out_x[j] = px;
    out_y[j] = py;
    out_z[j] = pz;
    const float qz = pz - oz;
    const float u = fx * (px - ox) / qz + cx, w = fy * (py - oy) / qz + cy;
    out_u[j] = u;
    out_w[j] = w;
    if (kKeys) out_key[j] = vertex_key(u, w);
  }
}

// Triangle (a, b, d) of a cluster: whether it reaches into z in [z_lo, z_hi] and its bounding
// box holds a pixel centre of `rect` (keep), and that box. When the box holds a single centre,
// as it mostly does for triangles smaller than a pixel, keep also says whether the triangle
// covers it (the same test as rasterize_triangle's).
struct TriangleBox {
  int x0, y0, x1, y1;
  bool keep;
};
inline TriangleBox triangle_box(int a, int b, int d, const float* __restrict pz,
                                const float* __restrict u, const float* __restrict w, float z_lo,
                                float z_hi, const PixelRect& rect) {
  const float z_min = std::min(std::min(pz[a], pz[b]), pz[d]);
  const float z_max = std::max(std::max(pz[a], pz[b]), pz[d]);
  // Pixel centres within the bounding box, with a hair of tolerance.
  const float tol = kBoxTolerance;
  const int x0 = std::max(int(std::ceil(std::min(std::min(u[a], u[b]), u[d]) - tol)), rect.x0);
  const int y0 = std::max(int(std::ceil(std::min(std::min(w[a], w[b]), w[d]) - tol)), rect.y0);
  const int x1 = std::min(int(std::floor(std::max(std::max(u[a], u[b]), u[d]) + tol)) + 1, rect.x1);
  const int y1 = std::min(int(std::floor(std::max(std::max(w[a], w[b]), w[d]) + tol)) + 1, rect.y1);
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
  const bool keep = (z_min <= z_hi) & (z_max >= z_lo) & (x0 < x1) & (y0 < y1) &
                    (std::abs(area) >= 1e-12f) & (!single | covers);
  return {x0, y0, x1, y1, keep};
}

// triangle_box for each triangle k (corners ca[k], cb[k], cc[k]). A vector loop (gathers
// through the corner indices); not inlined, as GCC 12 drops restrict qualifiers when inlining.
template <typename Index>
__attribute__((noinline)) void triangle_boxes(
    int n, const Index* __restrict ca, const Index* __restrict cb, const Index* __restrict cc,
    const float* __restrict pz, const float* __restrict u, const float* __restrict w, float z_lo,
    float z_hi, const PixelRect& rect, int* __restrict keep, int* __restrict bx0,
    int* __restrict by0, int* __restrict bx1, int* __restrict by1) {
  for (int k = 0; k < n; ++k) {
    const TriangleBox t = triangle_box(ca[k], cb[k], cc[k], pz, u, w, z_lo, z_hi, rect);
    keep[k] = t.keep;
    bx0[k] = t.x0;
    by0[k] = t.y0;
    bx1[k] = t.x1;
    by1[k] = t.y1;
  }
}

// Bit k of mask[k / 64]: triangle k's box may hold a pixel centre (see vertex_key); a superset
// of triangle_box's keep.
void triangles_near_centres(int n, const std::uint8_t* __restrict ca,
                            const std::uint8_t* __restrict cb, const std::uint8_t* __restrict cc,
                            const std::uint32_t* __restrict key, std::uint64_t* mask) {
  for (int k0 = 0; k0 < n; k0 += 64) {
    std::uint64_t m = 0;
    for (int k = k0; k < std::min(n, k0 + 64); ++k) {
      const std::uint32_t a = key[ca[k]], b = key[cb[k]], d = key[cc[k]];
      const std::uint32_t x = (a ^ b) | (a ^ d) | ((a | b | d) & 0x80008000u);
      m |= std::uint64_t(((x >> 16) != 0) & ((x & 0xFFFFu) != 0)) << (k - k0);
    }
    mask[k0 / 64] = m;
  }
}

// Triangles [0, n) with corners a, b, d into v's candidates where keep says so, listed without
// branches: for triangles smaller than a pixel that is a coin toss, which a branch would
// mostly mispredict.
template <typename Index>
void list_candidates(int n, const Index* a, const Index* b, const Index* d, const int* keep,
                     const int* x0, const int* y0, const int* x1, const int* y1, ClusterInView& v) {
  int count = 0;
  for (int k = 0; k < n; ++k) {
    v.a[count] = a[k];
    v.b[count] = b[k];
    v.d[count] = d[k];
    v.box[count] = {x0[k], y0[k], x1[k], y1[k]};
    count += keep[k];
  }
  v.count = count;
}

// One cluster's candidate triangles (its vertices in v).
void candidate_triangles(const TriangleClusters& c, const TriangleClusters::Cluster& cl, float z_lo,
                         float z_hi, const PixelRect& rect, ClusterInView& v) {
  constexpr int kMax = TriangleClusters::kMaxTriangles;
  int keep[kMax], x0[kMax], y0[kMax], x1[kMax], y1[kMax];
  const std::size_t f = std::size_t(cl.first_triangle);
  const std::uint8_t *ca = &c.corner_a[f], *cb = &c.corner_b[f], *cc = &c.corner_c[f];
  triangle_boxes(cl.triangle_count, ca, cb, cc, v.pz, v.u, v.w, z_lo, z_hi, rect, keep, x0, y0, x1,
                 y1);
  list_candidates(cl.triangle_count, ca, cb, cc, keep, x0, y0, x1, y1, v);
}

// The candidate triangles of a batch of clusters of triangles smaller than a pixel,
// clusters[0, n), whose vertices and triangles fit in v: their vertices (with keys) into v,
// then the few triangles whose keys say that their box may hold a pixel centre through
// triangle_box together, as one vector loop.
void small_candidate_triangles(const TriangleClusters& c, const int* clusters, int n,
                               const View& view, float z_lo, float z_hi, const PixelRect& rect,
                               ClusterInView& v) {
  // The vertices, one call per run of clusters that follow each other in c (and so do their
  // vertices).
  for (int i = 0, first = 0; i < n;) {
    const std::size_t f = std::size_t(c.clusters[clusters[i]].first_vertex);
    int count = 0, j = i;
    do {
      count += c.clusters[clusters[j]].vertex_count;
      ++j;
    } while (j < n && clusters[j] == clusters[j - 1] + 1);
    transform_vertices<true>(count, &c.x[f], &c.y[f], &c.z[f], view, v, first);
    first += count;
    i = j;
  }
  // The key test, cluster by cluster; its survivors with their corners' indices into v.
  int a[ClusterInView::kCandidates], b[ClusterInView::kCandidates], d[ClusterInView::kCandidates];
  int survivors = 0;
  for (int i = 0, first = 0; i < n; ++i) {
    const auto& cl = c.clusters[clusters[i]];
    const std::size_t f = std::size_t(cl.first_triangle);
    const std::uint8_t *ca = &c.corner_a[f], *cb = &c.corner_b[f], *cc = &c.corner_c[f];
    std::uint64_t mask[2];
    triangles_near_centres(cl.triangle_count, ca, cb, cc, v.key + first, mask);
    for (int k0 = 0; k0 < cl.triangle_count; k0 += 64) {
      for (std::uint64_t m = mask[k0 / 64]; m != 0; m &= m - 1) {
        const int k = k0 + __builtin_ctzll(m);
        a[survivors] = first + ca[k];
        b[survivors] = first + cb[k];
        d[survivors] = first + cc[k];
        ++survivors;
      }
    }
    first += cl.vertex_count;
  }
  int keep[ClusterInView::kCandidates], x0[ClusterInView::kCandidates],
      y0[ClusterInView::kCandidates], x1[ClusterInView::kCandidates],
      y1[ClusterInView::kCandidates];
  triangle_boxes(survivors, a, b, d, v.pz, v.u, v.w, z_lo, z_hi, rect, keep, x0, y0, x1, y1);
  list_candidates(survivors, a, b, d, keep, x0, y0, x1, y1, v);
}

// A triangle ready to draw: its corners in pixel coordinates, edge-function sign and tolerance,
// its plane (a pixel's ray with direction d meets it at t = n_dot_p0 / (n . d)) and its corners'
// range of t (camera depth, as the rays' d.z = 1).
struct TriangleSetup {
  float u[3], w[3];
  float s, eps;
  float nx, ny, nz, n_dot_p0;
  float t_lo, t_hi;
};

// A pixel's hit on the triangle's plane, kept within the triangle's depth range (a NaN stays
// NaN, for the tests after it to reject).
inline float hit_in_range(const TriangleSetup& t, float t_hit) {
  t_hit = t_hit < t.t_lo ? t.t_lo : t_hit;
  return t_hit > t.t_hi ? t.t_hi : t_hit;
}

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
    // Seen edge-on (n_dot_d = 0) the hit is +-inf, held to the depth range, or NaN, which the
    // tests below reject.
    const float t_hit = hit_in_range(t, n_dot_p0 / n_dot_d);
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
    const float t_hit = hit_in_range(t, t.n_dot_p0 / n_dot_d);
    const bool inside = (fx[k] < float(x1)) & (fy[k] < float(y1));
    const bool h = inside & (e0 >= t.eps) & (e1 >= t.eps) & (e2 >= t.eps) &
                   (t_hit >= t_gel[k] - slab) & (t_hit < old_t[k]);
    new_t[k] = h ? t_hit : old_t[k];
  }
  for (int k = kLanes - 1; k >= 0; --k) hit_t[index[k]] = new_t[k];
}

// One triangle (corners a, b, d of v's vertices) into the raster, over the pixel centres of box.
void rasterize_triangle(const ClusterInView& v, int a, int b, int d, const PixelRect& box,
                        const Eigen::Vector3f& o, SlabRaster& out) {
  TriangleSetup t = {{v.u[a], v.u[b], v.u[d]}, {v.w[a], v.w[b], v.w[d]}, 0, 0, 0, 0, 0, 0, 0, 0};
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
  t.t_lo = std::min(std::min(p0.z(), p1.z()), p2.z()) - o.z();
  t.t_hi = std::max(std::max(p0.z(), p1.z()), p2.z()) - o.z();
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
  // Clusters of triangles shorter than a pixel go in batches through the vertex keys; the others
  // one by one through triangle_boxes.
  const float small_m = out.small_triangle_px / float(g.px_per_m);
  const auto small = [&](int ci) { return c.clusters[ci].longest_edge < small_m; };
  ClusterInView v;
  for (std::size_t i = 0; i < clusters.size();) {
    const auto& cl = c.clusters[clusters[i]];
    if (small(clusters[i])) {
      std::size_t end = i;
      int vertices = 0, triangles = 0;
      while (end < clusters.size() && small(clusters[end])) {
        const auto& next = c.clusters[clusters[end]];
        if (vertices + next.vertex_count > ClusterInView::kVertices ||
            triangles + next.triangle_count > ClusterInView::kCandidates) {
          break;
        }
        vertices += next.vertex_count;
        triangles += next.triangle_count;
        ++end;
      }
      small_candidate_triangles(c, &clusters[i], int(end - i), view, z_bottom, z_top, out.rect, v);
      i = end;
    } else {
      const std::size_t f = std::size_t(cl.first_vertex);
      transform_vertices<false>(cl.vertex_count, &c.x[f], &c.y[f], &c.z[f], view, v);
      candidate_triangles(c, cl, z_bottom, z_top, out.rect, v);
      ++i;
    }
    for (int j = 0; j < v.count; ++j) {
      rasterize_triangle(v, v.a[j], v.b[j], v.d[j], v.box[j], view.o, out);
    }
  }
}

}  // namespace pg
