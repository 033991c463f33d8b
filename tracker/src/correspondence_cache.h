#pragma once
// Per-source-point nearest neighbours that survive between ICP iterations: a query is repeated
// only when the point has moved far enough that its nearest target point could have changed.
#include <Eigen/Core>
#include <cmath>
#include <vector>

#include "pg/tracker/kd_tree.h"

namespace pg {

class CorrespondenceCache {
 public:
  void reset(std::size_t n) {
    queried_at_.resize(n);
    slack_sq_.resize(n);
    second_.resize(n);
    nearest_.assign(n, kNeverQueried);
  }

  // The nearest target point of source point i, now at p (-1: none within `radius`). Exact: the
  // nearest point cannot have changed while p moved by less than half the gap between its
  // nearest and second-nearest distances at the last query (every distance changes by at most
  // the displacement); nor can a point with no target point within `radius` have come within
  // `max_correspondence` of one before moving by the difference. Otherwise it queries the tree,
  // seeded with the previous answers, and counts the query. (Seeding a first query with the
  // answers of the previous source point, a neighbour in raster order, was slower.)
  int nearest(std::size_t i, const Eigen::Vector3f& p, const PointCloudTree& tree, float radius,
              float max_correspondence, long& queries) {
    const int previous = nearest_[i];
    // Compared squared: a square root per point per iteration cost more than the rest of the
    // test.
    if (previous != kNeverQueried && (p - queried_at_[i]).squaredNorm() < slack_sq_[i]) {
      return previous;
    }
    const bool seen = previous != kNeverQueried;
    const PointCloudTree::TwoNearest nn =
        tree.nearest_two(p, radius, seen ? previous : -1, seen ? second_[i] : -1);
    queried_at_[i] = p;
    nearest_[i] = nn.index[0];
    second_[i] = nn.index[1];
    const float slack = nn.index[0] >= 0
                            ? 0.5f * (std::sqrt(nn.distance_sq[1]) - std::sqrt(nn.distance_sq[0]))
                            : radius - max_correspondence;
    slack_sq_[i] = slack > 0.0f ? slack * slack : 0.0f;
    ++queries;
    return nn.index[0];
  }

 private:
  static constexpr int kNeverQueried = -2;
  std::vector<Eigen::Vector3f> queried_at_;  // where each point was at its last query
  // The squared distance the point may move before its nearest neighbour could change:
  // ((d2 - d1) / 2)^2 from the nearest and second-nearest distances d1, d2 at the last query, or
  // (radius - max_correspondence)^2 when nothing was within the radius [m^2].
  std::vector<float> slack_sq_;
  std::vector<int> nearest_, second_;  // nearest and second nearest then (-1: none within radius)
};

}  // namespace pg
