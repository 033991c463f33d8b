#pragma once
// Per-source-point nearest neighbours that survive between ICP iterations: a query is repeated
// only when the point has moved far enough that its nearest target point could have changed.
#include <Eigen/Core>
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>
#endif
#include <cmath>
#include <vector>

#include "pg/tracker/kd_tree.h"

namespace pg {

class CorrespondenceCache {
 public:
  void reset(std::size_t n) {
    qx_.resize(n);
    qy_.resize(n);
    qz_.resize(n);
    slack_sq_.resize(n);
    second_.resize(n);
    nearest_.assign(n, kNeverQueried);
  }

  // The nearest target point of source point i, now at p (-1: none within `radius`). Exact: the
  // nearest point cannot have changed while p moved by less than half the gap between its
  // nearest and second-nearest distances at the last query (every distance changes by at most
  // the displacement); nor can a point with no target point within `radius` have come within
  // `max_correspondence` of one before moving by the difference. Otherwise it queries the tree
  // (query()).
  int nearest(std::size_t i, const Eigen::Vector3f& p, const PointCloudTree& tree, float radius,
              float max_correspondence, long& queries) {
    // Compared squared: a square root per point per iteration cost more than the rest of the
    // test.
    const float dx = p.x() - qx_[i], dy = p.y() - qy_[i], dz = p.z() - qz_[i];
    if (nearest_[i] != kNeverQueried && dx * dx + dy * dy + dz * dz < slack_sq_[i]) {
      return nearest_[i];
    }
    return query(i, p, tree, radius, max_correspondence, queries);
  }

  // Queries the tree for point i at p, seeded with the previous answers (they only prune: the
  // result is exact), remembers the answer and its slack, and counts the query. (Seeding a first
  // query with the answers of the previous source point, a neighbour in raster order, was
  // slower.)
  int query(std::size_t i, const Eigen::Vector3f& p, const PointCloudTree& tree, float radius,
            float max_correspondence, long& queries) {
    const int previous = nearest_[i];
    const bool seen = previous != kNeverQueried;
    const PointCloudTree::TwoNearest nn =
        tree.nearest_two(p, radius, seen ? previous : -1, seen ? second_[i] : -1);
    qx_[i] = p.x();
    qy_[i] = p.y();
    qz_[i] = p.z();
    nearest_[i] = nn.index[0];
    second_[i] = nn.index[1];
    const float slack = nn.index[0] >= 0
                            ? 0.5f * (std::sqrt(nn.distance_sq[1]) - std::sqrt(nn.distance_sq[0]))
                            : radius - max_correspondence;
    slack_sq_[i] = slack > 0.0f ? slack * slack : 0.0f;
    ++queries;
    return nn.index[0];
  }

#if defined(__AVX512F__)
  // nearest()'s test for the 16 points with indices `index` (the lanes in `lanes`), now at
  // (x, y, z): the lanes whose cached answer still holds; those answers in `answer`.
  __mmask16 still_valid(__m512i index, __mmask16 lanes, __m512 x, __m512 y, __m512 z,
                        __m512i& answer) const {
    const __m512 dx = _mm512_sub_ps(x, _mm512_mask_i32gather_ps(x, lanes, index, qx_.data(), 4));
    const __m512 dy = _mm512_sub_ps(y, _mm512_mask_i32gather_ps(y, lanes, index, qy_.data(), 4));
    const __m512 dz = _mm512_sub_ps(z, _mm512_mask_i32gather_ps(z, lanes, index, qz_.data(), 4));
    const __m512 d_sq = _mm512_fmadd_ps(dx, dx, _mm512_fmadd_ps(dy, dy, _mm512_mul_ps(dz, dz)));
    const __m512 slack_sq =
        _mm512_mask_i32gather_ps(_mm512_setzero_ps(), lanes, index, slack_sq_.data(), 4);
    answer = _mm512_mask_i32gather_epi32(_mm512_set1_epi32(kNeverQueried), lanes, index,
                                         nearest_.data(), 4);
    return _mm512_mask_cmp_ps_mask(lanes, d_sq, slack_sq, _CMP_LT_OQ) &
           _mm512_cmpneq_epi32_mask(answer, _mm512_set1_epi32(kNeverQueried));
  }
#elif defined(__AVX2__) && defined(__FMA__)
  // The same for 8 points, with lane masks of all ones or zeros.
  __m256i still_valid(__m256i index, __m256i lanes, __m256 x, __m256 y, __m256 z,
                      __m256i& answer) const {
    const __m256 zero = _mm256_setzero_ps(), lanes_ps = _mm256_castsi256_ps(lanes);
    const auto gather = [&](const float* base) {
      return _mm256_mask_i32gather_ps(zero, base, index, lanes_ps, 4);
    };
    const __m256 dx = _mm256_sub_ps(x, gather(qx_.data()));
    const __m256 dy = _mm256_sub_ps(y, gather(qy_.data()));
    const __m256 dz = _mm256_sub_ps(z, gather(qz_.data()));
    const __m256 d_sq = _mm256_fmadd_ps(dx, dx, _mm256_fmadd_ps(dy, dy, _mm256_mul_ps(dz, dz)));
    const __m256i never = _mm256_set1_epi32(kNeverQueried);
    answer = _mm256_mask_i32gather_epi32(never, nearest_.data(), index, lanes, 4);
    const __m256i moved_less =
        _mm256_castps_si256(_mm256_cmp_ps(d_sq, gather(slack_sq_.data()), _CMP_LT_OQ));
    return _mm256_andnot_si256(_mm256_cmpeq_epi32(answer, never),
                               _mm256_and_si256(lanes, moved_less));
  }
#endif

 private:
  static constexpr int kNeverQueried = -2;
  std::vector<float> qx_, qy_, qz_;  // where each point was at its last query
  // The squared distance the point may move before its nearest neighbour could change:
  // ((d2 - d1) / 2)^2 from the nearest and second-nearest distances d1, d2 at the last query, or
  // (radius - max_correspondence)^2 when nothing was within the radius [m^2].
  std::vector<float> slack_sq_;
  std::vector<int> nearest_, second_;  // nearest and second nearest then (-1: none within radius)
};

}  // namespace pg
