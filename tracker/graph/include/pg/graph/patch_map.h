#pragma once
// The local patch (paper section IV-C): key-frame clouds fused in the object frame with the
// estimates current when each was added, averaged per voxel, with a k-d tree for registration.
// Reset at every new contact episode. For the GroundtruthPatch baseline it holds a fixed model.
#include <array>
#include <cstdint>
#include <map>
#include <memory>

#include "pg/tracker/kd_tree.h"
#include "pg/tracker/point_cloud.h"

namespace pg {

struct PatchMapOptions {
  int keyframe_interval = 10;  // frames between key frames (the reference code: 10 sim, 5 real)
  // Voxel edge of the fused patch [m]: each voxel of a grid fixed in the object frame holds the
  // mean of every key-frame point that fell in it; 0 keeps every point.
  double voxel_m = 1e-4;
};

class PatchMap {
 public:
  explicit PatchMap(PatchMapOptions options = {}) : options_(options) {}

  void reset();
  // Moves a key frame's cloud into the object frame and fuses it; rebuilds the tree.
  void add_keyframe(const PointCloud& cloud_sensor, const SE3& T_object_sensor);
  // A fixed model (object frame) instead of key frames: the GroundtruthPatch baseline.
  void set_model(const PointCloud& model_object);

  bool empty() const { return !tree_; }
  const PointCloudTree& tree() const { return *tree_; }
  const PointCloud& cloud_object() const { return fused_; }
  int keyframes() const { return keyframes_; }
  const PatchMapOptions& options() const { return options_; }

 private:
  // Running sums of every key frame's points and normals per voxel of a grid fixed in the object
  // frame: each voxel's point is the mean of all that fell in it, whichever key frame brought
  // them. (Re-voxelising the fused points with each key frame, on a grid placed at the
  // cloud's corner, averaged averages on a shifted grid every time: the patch blurred, and its
  // newest key frame weighed as much as all the others; long episodes drifted in rotation.)
  struct VoxelSum {
    Eigen::Vector3d point_sum = Eigen::Vector3d::Zero();
    Eigen::Vector3d normal_sum = Eigen::Vector3d::Zero();
    int count = 0;
  };
  std::map<std::array<std::int64_t, 3>, VoxelSum> voxels_;  // ordered: a deterministic patch

  PatchMapOptions options_;
  PointCloud fused_;
  std::unique_ptr<PointCloudTree> tree_;
  int keyframes_ = 0;
};

}  // namespace pg
