#include "pg/graph/patch_map.h"

#include "pg/core/point_io.h"

namespace pg {

void PatchMap::reset() {
  fused_.clear();
  tree_.reset();
  keyframes_ = 0;
}

void PatchMap::add_keyframe(const PointCloud& cloud_sensor, const SE3& T_object_sensor) {
  PointCloud all = transform_cloud(T_object_sensor, cloud_sensor);
  all.points.insert(all.points.end(), fused_.points.begin(), fused_.points.end());
  all.normals.insert(all.normals.end(), fused_.normals.begin(), fused_.normals.end());
  voxel_downsample(all, options_.voxel_m, fused_);
  tree_ = std::make_unique<PointCloudTree>(fused_);
  ++keyframes_;
}

void PatchMap::set_model(const PointCloud& model_object) {
  fused_ = model_object;
  tree_ = std::make_unique<PointCloudTree>(fused_);
  keyframes_ = 0;
}

void PatchMap::save_ply(const std::string& path) const {
  write_ply(path, fused_.points, &fused_.normals);
}

}  // namespace pg
