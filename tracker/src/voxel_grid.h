#pragma once
// An exact nearest-neighbour grid for the tracker's surface-like clouds (contact clouds, object
// patches): the points sorted into cubic cells of edge h (a dense CSR layout: one offset per
// cell, the points of a cell contiguous). A query visits rings of cells around its own cell
// (ring k: the cells at Chebyshev distance k), skipping every cell whose box is farther than the
// current k-th best, and stops as soon as no unvisited cell can hold a nearer point. So the answer
// is exact; near the surface (the common case in ICP) it costs one or two rings, a few dozen
// distances, where a k-d tree descends ~12 levels with a branch per level. Far from every point
// it gives up after `max_rings` and says so, and the caller finishes with its k-d tree.
//
// The cell edge is about twice the point spacing (a handful of points per occupied cell), found
// from the bounding box and corrected once by the measured occupancy; the cell count is capped,
// so a cloud with a huge bounding box gets coarser cells, never a huge grid.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace pg {

class VoxelGrid {
 public:
  // Points per occupied cell (about (h / spacing)^2 on a surface): fewer means fewer distances
  // per query but more queries that the 3x3x3 block cannot settle (2.25 and 6 were no faster
  // on the ICP benchmark; 2.25 sent 29% of the queries on to ring 2, 4 sends 22%).
  static constexpr float kPointsPerCell = 4.0f;
  static constexpr std::size_t kMaxCells = std::size_t(1) << 21;  // 8 MB of offsets at most

  VoxelGrid() = default;
  explicit VoxelGrid(const std::vector<Eigen::Vector3f>& points) { build(points); }

  // False when the grid could not be built (no points, or a non-finite coordinate): every query
  // must then go to the k-d tree.
  bool valid() const { return !entries_.empty(); }
  float cell_edge() const { return h_; }

  // Offers the points near `query` to `result` (nanoflann's result-set interface: addPoint(d_sq,
  // index), worstDist()), nearest cells first. True when every point not offered is at least
  // sqrt(result.worstDist()) from the query, i.e. the result is final; false when it stopped
  // after max_rings rings without being sure.
  template <class ResultSet>
  bool search(const Eigen::Vector3f& query, ResultSet& result, int max_rings) const;

 private:
  struct Entry {
    float x, y, z;
    std::uint32_t index;  // in the cloud the grid was built from
  };

  void build(const std::vector<Eigen::Vector3f>& points);
  std::size_t count_cells(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& lower,
                          const Eigen::Vector3f& extent, float h);
  template <class ResultSet>
  bool search_block(const Eigen::Vector3f& query, const float (&u)[3], const int (&c)[3],
                    ResultSet& result) const;
  std::size_t cell_of(const Eigen::Vector3f& p) const {
    const auto axis = [&](int a) {
      const int c = int((p[a] - origin_[a]) * inv_h_);
      return std::size_t(std::clamp(c, 0, dims_[a] - 1));
    };
    return (axis(2) * std::size_t(dims_[1]) + axis(1)) * std::size_t(dims_[0]) + axis(0);
  }

  Eigen::Vector3f origin_ = Eigen::Vector3f::Zero();  // corner of cell (0, 0, 0) [m]
  float h_ = 0, inv_h_ = 0;                           // cell edge [m], its inverse [1/m]
  int dims_[3] = {0, 0, 0};
  std::vector<std::uint32_t> start_;  // cell c holds entries_[start_[c], start_[c + 1])
  std::vector<Entry> entries_;
};

// Cell dimensions for edge h (grown until the grid has at most kMaxCells cells) and the count of
// points per cell in start_[c + 1]. Returns the number of occupied cells.
inline std::size_t VoxelGrid::count_cells(const std::vector<Eigen::Vector3f>& points,
                                          const Eigen::Vector3f& lower,
                                          const Eigen::Vector3f& extent, float h) {
  std::size_t cells = 1;
  for (;; h *= 1.25f) {
    cells = 1;
    for (int a = 0; a < 3; ++a) {
      // One empty cell on each side: every point's 3x3x3 block exists (the fast path).
      dims_[a] = int(std::min(extent[a] / h, 1e6f)) + 3;
      cells *= std::size_t(dims_[a]);
    }
    if (cells <= kMaxCells) break;
  }
  h_ = h;
  inv_h_ = 1.0f / h;
  origin_ = lower - Eigen::Vector3f::Constant(h);
  start_.assign(cells + 1, 0);
  for (const auto& p : points) ++start_[cell_of(p) + 1];
  std::size_t occupied = 0;
  for (std::size_t c = 1; c <= cells; ++c) occupied += start_[c] != 0;
  return occupied;
}

inline void VoxelGrid::build(const std::vector<Eigen::Vector3f>& points) {
  if (points.empty() || points.size() >= std::numeric_limits<std::uint32_t>::max()) return;
  Eigen::Vector3f lower = points[0], upper = points[0];
  for (const auto& p : points) {
    if (!p.allFinite()) return;
    lower = lower.cwiseMin(p);
    upper = upper.cwiseMax(p);
  }
  const Eigen::Vector3f extent = upper - lower;
  // A surface seen from its bounding box: the two largest extents span about its area, so
  // kPointsPerCell points per occupied cell for h = sqrt(kPointsPerCell area / n). Curved or
  // closed surfaces have more area than that; the measured occupancy corrects h once (occupancy
  // ~ h^2 on a surface).
  Eigen::Vector3f sorted = extent;
  std::sort(sorted.data(), sorted.data() + 3);
  const float n = float(points.size());
  const float tiny = 1e-6f * std::max(sorted[2], 1e-9f);
  float h = std::max(std::sqrt(kPointsPerCell * sorted[1] * sorted[2] / n), tiny);
  const float occupancy = n / float(count_cells(points, lower, extent, h));
  if (occupancy < 0.5f * kPointsPerCell || occupancy > 2.0f * kPointsPerCell) {
    count_cells(points, lower, extent, std::max(h_ * std::sqrt(kPointsPerCell / occupancy), tiny));
  }
  // Offsets from the counts, then the points in cell order.
  const std::size_t cells = start_.size() - 1;
  for (std::size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
  entries_.resize(points.size());
  std::vector<std::uint32_t> next(start_.begin(), start_.end() - 1);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f& p = points[i];
    entries_[next[cell_of(p)]++] = {p.x(), p.y(), p.z(), std::uint32_t(i)};
  }
}

// Rings 0 and 1 at once, for a query whose cell is not on the grid's border. The 3x3x3 block is
// nine rows of three consecutive cells, whose points are consecutive in entries_; the query's own
// row goes first, and a row, or a row's end cell, is skipped when its box is farther than the
// current second-best distance. Near the surface that leaves about 8 of the 27 cells. True when
// the block settles the answer.
template <class ResultSet>
bool VoxelGrid::search_block(const Eigen::Vector3f& query, const float (&u)[3], const int (&c)[3],
                             ResultSet& result) const {
  const float h_bound = h_ * (1.0f - 1e-4f);  // see search()
  // Squared distances from the query to the neighbouring slabs below / above, per axis.
  float below[3], above[3];
  for (int a = 0; a < 3; ++a) {
    below[a] = (u[a] - float(c[a])) * h_bound;
    above[a] = (float(c[a] + 1) - u[a]) * h_bound;
    below[a] *= below[a];
    above[a] *= above[a];
  }
  const auto slab = [&](int a, int d) { return d < 0 ? below[a] : d > 0 ? above[a] : 0.0f; };
  static constexpr int kRows[9][2] = {{0, 0},  {-1, 0}, {1, 0},  {0, -1}, {0, 1},
                                      {-1, -1}, {-1, 1}, {1, -1}, {1, 1}};
  for (const auto& zy : kRows) {
    const float s_zy = slab(2, zy[0]) + slab(1, zy[1]);
    if (s_zy >= result.worstDist()) continue;
    const std::size_t row =
        (std::size_t(c[2] + zy[0]) * dims_[1] + std::size_t(c[1] + zy[1])) * dims_[0] + c[0];
    const std::uint32_t begin = start_[row - (s_zy + below[0] < result.worstDist() ? 1 : 0)];
    const std::uint32_t end = start_[row + (s_zy + above[0] < result.worstDist() ? 2 : 1)];
    for (std::uint32_t e = begin; e < end; ++e) {
      const Entry& p = entries_[e];
      const float dx = p.x - query.x(), dy = p.y - query.y(), dz = p.z - query.z();
      const float d_sq = dx * dx + dy * dy + dz * dz;
      if (d_sq < result.worstDist()) result.addPoint(d_sq, p.index);
    }
  }
  // Every other point lies beyond one of the block's six faces.
  float bound = std::numeric_limits<float>::infinity();
  for (int a = 0; a < 3; ++a) {
    bound = std::min({bound, u[a] - float(c[a] - 1), float(c[a] + 2) - u[a]});
  }
  bound *= h_bound;
  return bound * bound >= result.worstDist();
}

template <class ResultSet>
bool VoxelGrid::search(const Eigen::Vector3f& query, ResultSet& result, int max_rings) const {
  // Bounds use a cell edge shortened by more than the float rounding of the cell coordinates, so
  // no point is pruned by a bound that rounding made a hair too large.
  const float h_bound = h_ * (1.0f - 1e-4f);
  // The query in cell units, and the nearest cell of the grid (the query may lie outside it).
  float u[3];
  int c[3];
  float outside_sq = 0;  // squared distance from the query to the grid's box [m^2]
  for (int a = 0; a < 3; ++a) {
    u[a] = std::clamp((query[a] - origin_[a]) * inv_h_, -1e6f, 1e6f);
    c[a] = std::clamp(int(std::floor(u[a])), 0, dims_[a] - 1);
    const float out = std::max({0.0f, -u[a], u[a] - float(dims_[a])}) * h_bound;
    outside_sq += out * out;
  }
  if (outside_sq >= result.worstDist()) return true;
  int first_ring = 0;
  if (c[0] >= 1 && c[0] <= dims_[0] - 2 && c[1] >= 1 && c[1] <= dims_[1] - 2 && c[2] >= 1 &&
      c[2] <= dims_[2] - 2) {
    if (search_block(query, u, c, result)) return true;
    first_ring = 2;
  }
  // Squared distance from the query to the slab of cells at offset d along axis a.
  const auto slab_sq = [&](int a, int d) {
    const float lo = float(c[a] + d);
    const float t = std::max({0.0f, lo - u[a], u[a] - lo - 1.0f}) * h_bound;
    return t * t;
  };
  const auto scan = [&](std::size_t cell) {
    for (std::uint32_t e = start_[cell]; e < start_[cell + 1]; ++e) {
      const Entry& p = entries_[e];
      const float dx = p.x - query.x(), dy = p.y - query.y(), dz = p.z - query.z();
      const float d_sq = dx * dx + dy * dy + dz * dz;
      if (d_sq < result.worstDist()) result.addPoint(d_sq, p.index);
    }
  };
  for (int k = first_ring; k <= max_rings; ++k) {
    // Ring k: the cells with max(|dx|, |dy|, |dz|) = k, each skipped when its box is too far.
    for (int dz = -k; dz <= k; ++dz) {
      const int z = c[2] + dz;
      if (z < 0 || z >= dims_[2]) continue;
      const float sz = slab_sq(2, dz);
      if (sz >= result.worstDist()) continue;
      for (int dy = -k; dy <= k; ++dy) {
        const int y = c[1] + dy;
        if (y < 0 || y >= dims_[1]) continue;
        const float syz = sz + slab_sq(1, dy);
        if (syz >= result.worstDist()) continue;
        const std::size_t row = (std::size_t(z) * dims_[1] + std::size_t(y)) * dims_[0];
        const bool on_ring = dz == -k || dz == k || dy == -k || dy == k;
        const int step = on_ring || k == 0 ? 1 : 2 * k;  // inside the ring only dx = -k, +k
        for (int dx = -k; dx <= k; dx += step) {
          const int x = c[0] + dx;
          if (x < 0 || x >= dims_[0] || syz + slab_sq(0, dx) >= result.worstDist()) continue;
          scan(row + std::size_t(x));
        }
      }
    }
    // Every unvisited cell lies beyond one of the block's faces that still has grid behind it.
    float bound = std::numeric_limits<float>::infinity();
    for (int a = 0; a < 3; ++a) {
      if (c[a] - k > 0) bound = std::min(bound, u[a] - float(c[a] - k));
      if (c[a] + k < dims_[a] - 1) bound = std::min(bound, float(c[a] + k + 1) - u[a]);
    }
    if (bound == std::numeric_limits<float>::infinity()) return true;  // the whole grid seen
    bound = std::max(bound, 0.0f) * h_bound;
    if (bound * bound >= result.worstDist()) return true;
  }
  return false;
}

}  // namespace pg
