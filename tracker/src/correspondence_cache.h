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
    d1_.resize(n);
    d2_.resize(n);
    second_.resize(n);
    nearest_.assign(n, kNeverQueried);
  }

  // The nearest target point of source point i, now at p (-1: none within `radius`). Exact: the
  // nearest point cannot have changed while p moved by less than half the gap between its
  // nearest and second-nearest distances at the last query (every distance changes by at most
  // the displacement); nor can a point with no target point within `radius` have come within
  // `max_correspondence` of one before moving by the difference. Otherwise it queries the tree,
  // seeded with the previous answer, and counts the query.
  int nearest(std::size_t i, const Eigen::Vector3f& p, const PointCloudTree& tree, float radius,
              float max_correspondence, long& queries) {
    const int previous = nearest_[i];
    if (previous != kNeverQueried) {
      const float moved = (p - queried_at_[i]).norm();
      const bool same = previous >= 0 ? 2.0f * moved < d2_[i] - d1_[i]
                                      : moved < radius - max_correspondence;
      if (same) return previous;
    }
    const bool seen = previous != kNeverQueried;
    const PointCloudTree::TwoNearest nn =
        tree.nearest_two(p, radius, seen ? previous : -1, seen ? second_[i] : -1);
    queried_at_[i] = p;
    nearest_[i] = nn.index[0];
    second_[i] = nn.index[1];
    d1_[i] = std::sqrt(nn.distance_sq[0]);
    d2_[i] = std::sqrt(nn.distance_sq[1]);
    ++queries;
    return nn.index[0];
  }

 private:
  static constexpr int kNeverQueried = -2;
  std::vector<Eigen::Vector3f> queried_at_;  // where each point was at its last query
  std::vector<float> d1_, d2_;               // nearest and second-nearest distances then [m]
  std::vector<int> nearest_, second_;        // their indices (-1: none within the radius)
};

}  // namespace pg
