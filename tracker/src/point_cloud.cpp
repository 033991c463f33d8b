#include "pg/tracker/point_cloud.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

namespace pg {

PointCloud transform_cloud(const SE3& T_b_a, const PointCloud& cloud_a) {
  const Eigen::Matrix3f R = T_b_a.rotation_matrix().cast<float>();
  const Eigen::Vector3f t = T_b_a.translation().cast<float>();
  PointCloud cloud_b;
  cloud_b.points.resize(cloud_a.points.size());
  cloud_b.normals.resize(cloud_a.normals.size());
  for (std::size_t i = 0; i < cloud_a.points.size(); ++i) cloud_b.points[i] = R * cloud_a.points[i] + t;
  for (std::size_t i = 0; i < cloud_a.normals.size(); ++i) cloud_b.normals[i] = R * cloud_a.normals[i];
  return cloud_b;
}

void voxel_downsample(const PointCloud& in, double voxel_m, PointCloud& out) {
  out.clear();
  if (voxel_m <= 0.0 || in.empty()) {
    out = in;
    return;
  }
  // Sort (voxel key, point index) pairs; each run of equal keys is one voxel. Keys pack three
  // 21-bit voxel coordinates: a cloud wider than 2^21 voxels along an axis is refused (it had
  // wrapped, merging points metres apart). Points that are not finite are left out.
  const float inv = float(1.0 / voxel_m);
  thread_local std::vector<std::pair<std::uint64_t, std::uint32_t>> keys;
  keys.clear();
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(INFINITY), hi = -lo;
  for (const auto& p : in.points) {
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (!(lo.x() <= hi.x())) return;  // no finite point
  if (!(double((hi - lo).maxCoeff()) / voxel_m < 2097151.0)) {
    throw std::invalid_argument(
        "voxel_downsample: the cloud spans " + std::to_string((hi - lo).maxCoeff()) +
        " m, more than 2^21 voxels of " + std::to_string(voxel_m) + " m along an axis");
  }
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (!in.points[i].allFinite()) continue;
    const Eigen::Vector3f v = (in.points[i] - lo) * inv;
    const auto cx = std::uint64_t(v.x()) & 0x1FFFFF, cy = std::uint64_t(v.y()) & 0x1FFFFF,
               cz = std::uint64_t(v.z()) & 0x1FFFFF;
    keys.push_back({(cx << 42) | (cy << 21) | cz, std::uint32_t(i)});
  }
  std::sort(keys.begin(), keys.end());
  const bool has_normals = in.normals.size() == in.points.size();
  for (std::size_t a = 0; a < keys.size();) {
    std::size_t b = a;
    Eigen::Vector3f p_sum = Eigen::Vector3f::Zero(), n_sum = Eigen::Vector3f::Zero();
    while (b < keys.size() && keys[b].first == keys[a].first) {
      p_sum += in.points[keys[b].second];
      if (has_normals) n_sum += in.normals[keys[b].second];
      ++b;
    }
    out.points.push_back(p_sum / float(b - a));
    if (has_normals) {
      const float len = n_sum.norm();
      out.normals.push_back(len > 0 ? Eigen::Vector3f(n_sum / len)
                                    : in.normals[keys[a].second]);
    }
    a = b;
  }
}

}  // namespace pg
