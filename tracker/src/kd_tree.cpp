#include "pg/tracker/kd_tree.h"

#include <nanoflann.hpp>
#include <stdexcept>
#include <string>

#include "voxel_grid.h"

namespace pg {

namespace {

// nanoflann's dataset interface over a PointCloud's points.
struct CloudAdaptor {
  const PointCloud* cloud = nullptr;
  std::size_t kdtree_get_point_count() const { return cloud->points.size(); }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const { return cloud->points[i][int(dim)]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

using KdIndex = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<float, CloudAdaptor>, CloudAdaptor, 3, std::uint32_t>;

// Result sets for nanoflann's findNeighbors: the k = 1 and k = 2 nearest within a radius. The
// radius is the initial worst distance, so whole branches beyond it are pruned.
struct NearestWithin {
  float best_sq;
  std::uint32_t best = 0;
  bool found = false;
  explicit NearestWithin(float radius_sq) : best_sq(radius_sq) {}
  bool addPoint(float d_sq, std::uint32_t i) {
    if (d_sq < best_sq) {
      best_sq = d_sq;
      best = i;
      found = true;
    }
    return true;
  }
  float worstDist() const { return best_sq; }
  bool full() const { return found; }
};

struct TwoNearestWithin {
  PointCloudTree::TwoNearest r;
  explicit TwoNearestWithin(float radius_sq) { r.distance_sq[0] = r.distance_sq[1] = radius_sq; }
  bool addPoint(float d_sq, std::uint32_t i) {
    if (int(i) == r.index[0] || int(i) == r.index[1]) return true;  // a hint met again
    if (d_sq < r.distance_sq[0]) {
      r.distance_sq[1] = r.distance_sq[0];
      r.index[1] = r.index[0];
      r.distance_sq[0] = d_sq;
      r.index[0] = int(i);
    } else if (d_sq < r.distance_sq[1]) {
      r.distance_sq[1] = d_sq;
      r.index[1] = int(i);
    }
    return true;
  }
  float worstDist() const { return r.distance_sq[1]; }
  bool full() const { return r.index[1] >= 0; }
};

// Rings of grid cells searched before a query is handed to the k-d tree: enough for queries
// within ~3 cells (~6 point spacings) of the surface, which is every ICP query once the guess is
// within the correspondence distance; farther ones gain nothing from the grid.
constexpr int kMaxGridRings = 3;

}  // namespace

struct PointCloudTree::Impl {
  PointCloud cloud;
  CloudAdaptor adaptor;
  KdIndex index;
  VoxelGrid grid;
  Impl(PointCloud c, int leaf_size, bool voxel_grid)
      : cloud(std::move(c)),
        adaptor{&cloud},
        index(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(std::size_t(leaf_size))) {
    if (voxel_grid) grid = VoxelGrid(cloud.points);
  }
  // The grid first; the k-d tree finishes (from the grid's partial answer) when the grid could
  // not decide. Exact either way.
  template <class ResultSet>
  void search(const Eigen::Vector3f& query, ResultSet& result) const {
    if (grid.valid() && grid.search(query, result, kMaxGridRings)) return;
    index.findNeighbors(result, query.data(), nanoflann::SearchParams());
  }
};

namespace {

// A NaN point splits no box: the tree's searches would then miss points, not only the NaN one.
PointCloud checked_for_nan(PointCloud cloud) {
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (cloud.points[i].hasNaN()) {
      throw std::invalid_argument("PointCloudTree: point " + std::to_string(i) +
                                  " is NaN; leave such points out (an organised cloud's invalid "
                                  "pixels, say)");
    }
  }
  return cloud;
}

}  // namespace

PointCloudTree::PointCloudTree(PointCloud cloud, int leaf_size, bool voxel_grid)
    : impl_(std::make_unique<Impl>(checked_for_nan(std::move(cloud)), std::max(leaf_size, 1),
                                   voxel_grid)) {}
PointCloudTree::~PointCloudTree() = default;
PointCloudTree::PointCloudTree(PointCloudTree&&) noexcept = default;
PointCloudTree& PointCloudTree::operator=(PointCloudTree&&) noexcept = default;

const PointCloud& PointCloudTree::cloud() const { return impl_->cloud; }
std::size_t PointCloudTree::size() const { return impl_->cloud.points.size(); }

int PointCloudTree::nearest(const Eigen::Vector3f& query, float max_distance_m,
                            float* distance_sq) const {
  // Nothing lies within a negative or NaN distance (squared, a negative one had searched as far).
  if (size() == 0 || !(max_distance_m >= 0)) return -1;
  NearestWithin result(max_distance_m * max_distance_m);
  impl_->search(query, result);
  if (!result.found) return -1;
  if (distance_sq) *distance_sq = result.best_sq;
  return int(result.best);
}

PointCloudTree::TwoNearest PointCloudTree::nearest_two(const Eigen::Vector3f& query,
                                                       float radius_m, int hint0,
                                                       int hint1) const {
  // Nothing lies within a negative or NaN radius (squared, a negative one had searched as far).
  if (!(radius_m >= 0)) radius_m = 0;
  TwoNearestWithin result(radius_m * radius_m);
  if (size() == 0) return result.r;
  // Seeding the result with the hints shrinks the search ball from the start; any nearer point
  // still replaces them, so the answer is exact.
  const auto& points = impl_->cloud.points;
  for (int h : {hint0, hint1}) {
    if (h >= 0 && std::size_t(h) < points.size()) {
      const float d_sq = (points[std::size_t(h)] - query).squaredNorm();
      if (d_sq < result.worstDist()) result.addPoint(d_sq, std::uint32_t(h));
    }
  }
  impl_->search(query, result);
  return result.r;
}

}  // namespace pg
