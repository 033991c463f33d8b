#include "pg/graph/patch_map.h"

namespace pg {

void PatchMap::reset() {
  voxels_.clear();
  fused_.clear();
  tree_.reset();
  keyframes_ = 0;
}

void PatchMap::add_keyframe(const PointCloud& cloud_sensor, const SE3& T_object_sensor) {
  const PointCloud moved = transform_cloud(T_object_sensor, cloud_sensor);
  const double inv = options_.voxel_m > 0 ? 1.0 / options_.voxel_m : 0.0;
  // Cell indices past this (a voxel edge 1e-15 of the coordinates) would overflow; such points,
  // and every point when voxel_m is 0, keep a cell of their own, numbered past any real one.
  constexpr double kMaxCell = 1e15;
  for (std::size_t i = 0; i < moved.size(); ++i) {
    const Eigen::Vector3d p = moved.points[i].cast<double>();
    const Eigen::Vector3d cell = (p * inv).array().floor();
    const std::array<std::int64_t, 3> key =
        inv > 0 && cell.cwiseAbs().maxCoeff() < kMaxCell
            ? std::array<std::int64_t, 3>{std::int64_t(cell.x()), std::int64_t(cell.y()),
                                          std::int64_t(cell.z())}
            : std::array<std::int64_t, 3>{std::int64_t(kMaxCell) + std::int64_t(voxels_.size()), 0,
                                          0};
    VoxelSum& v = voxels_[key];
    v.point_sum += p;
    v.normal_sum += moved.normals[i].cast<double>();
    ++v.count;
  }
  fused_.clear();
  fused_.reserve(voxels_.size());
  for (const auto& [key, v] : voxels_) {
    const double len = v.normal_sum.norm();
    if (!(len > 0)) continue;  // opposite normals cancelled: no plane to register against
    fused_.push_back((v.point_sum / v.count).cast<float>(),
                     Eigen::Vector3f((v.normal_sum / len).cast<float>()));
  }
  tree_ = std::make_unique<PointCloudTree>(fused_);
  ++keyframes_;
}

void PatchMap::set_model(const PointCloud& model_object) {
  voxels_.clear();
  fused_ = model_object;
  tree_ = std::make_unique<PointCloudTree>(fused_);
  keyframes_ = 0;
}

}  // namespace pg
