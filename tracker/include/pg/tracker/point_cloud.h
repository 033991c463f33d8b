#pragma once
// Points with surface normals, the currency between reconstruction and registration. The frame is
// in the variable's name (cloud_sensor, patch_object); the struct itself does not know it.
#include <Eigen/Core>
#include <vector>

#include "pg/core/se3.h"

namespace pg {

struct PointCloud {
  std::vector<Eigen::Vector3f> points;   // [m]
  std::vector<Eigen::Vector3f> normals;  // unit outward surface normals, one per point [-]

  std::size_t size() const { return points.size(); }
  bool empty() const { return points.empty(); }
  void clear() {
    points.clear();
    normals.clear();
  }
  void reserve(std::size_t n) {
    points.reserve(n);
    normals.reserve(n);
  }
  void push_back(const Eigen::Vector3f& p, const Eigen::Vector3f& n) {
    points.push_back(p);
    normals.push_back(n);
  }
};

// cloud_b = T_b_a * cloud_a (points moved, normals rotated).
PointCloud transform_cloud(const SE3& T_b_a, const PointCloud& cloud_a);

// One point per occupied voxel of edge voxel_m: the centroid of the voxel's points, with their
// mean normal re-normalised, in voxel-key order. `out` may not alias
// `in`; its buffers are reused. voxel_m <= 0 copies. Points that are not finite are left out;
// throws std::invalid_argument for a cloud wider than 2^21 voxels along an axis.
void voxel_downsample(const PointCloud& in, double voxel_m, PointCloud& out);

}  // namespace pg
