#pragma once
// Exact nearest-neighbour search over a cloud's points, built once and queried many times: the
// object patch of eq. 6 is registered against frame after frame without rebuilding. A voxel grid
// (src/voxel_grid.h) answers the queries within a few point spacings of the surface, which is
// every ICP query on the benchmark, about 1.1x faster than the k-d tree (nanoflann) alone; the
// k-d tree answers the rest. Immutable after construction, so queries may run on several threads
// at once.
#include <Eigen/Core>
#include <memory>

#include "pg/tracker/point_cloud.h"

namespace pg {

class PointCloudTree {
 public:
  // Takes the cloud (normals optional for queries, required as an ICP target). Build cost is
  // O(n log n): about 5 ms for 50k points, plus about a third for the grid. voxel_grid = false:
  // the k-d tree alone (same answers). Throws std::invalid_argument for a NaN point.
  explicit PointCloudTree(PointCloud cloud, int leaf_size = 12, bool voxel_grid = true);
  ~PointCloudTree();
  PointCloudTree(PointCloudTree&&) noexcept;
  PointCloudTree& operator=(PointCloudTree&&) noexcept;

  const PointCloud& cloud() const;
  std::size_t size() const;

  // The nearest point within max_distance_m: its index, or -1 (always for a negative or NaN
  // distance). distance_sq [m^2] if given.
  int nearest(const Eigen::Vector3f& query, float max_distance_m,
              float* distance_sq = nullptr) const;

  // The two nearest points within radius_m. Unfound slots have index -1 and distance_sq =
  // radius_m^2 (every other point is at least that far), which is what a caller needs to decide
  // later that a moved query still has the same nearest point (see icp.cpp). A negative or NaN
  // radius is 0: nothing found.
  struct TwoNearest {
    int index[2] = {-1, -1};
    float distance_sq[2] = {0, 0};  // [m^2], ascending
  };
  // hint0/hint1 (optional, -1: none): points near the answer, e.g. the previous answer for a query
  // that moved a little. They only prune the search; the result is exact either way.
  TwoNearest nearest_two(const Eigen::Vector3f& query, float radius_m, int hint0 = -1,
                         int hint1 = -1) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pg
