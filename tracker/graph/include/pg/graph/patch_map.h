#pragma once
// The local patch (paper section IV-C): key-frame clouds fused in the object frame with the
// estimates current when each was added, voxel-downsampled, with a k-d tree for registration.
// Reset at every new contact episode. For the GroundtruthPatch baseline it holds a fixed model.
#include <memory>
#include <string>

#include "pg/tracker/kd_tree.h"
#include "pg/tracker/point_cloud.h"

namespace pg {

struct PatchMapOptions {
  int keyframe_interval = 10;  // frames between key frames (the reference code: 10 sim, 5 real)
  double voxel_m = 1e-4;       // voxel edge of the fused patch [m]
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

  // Binary PLY with normals (object frame). Throws InputError naming the path.
  void save_ply(const std::string& path) const;

 private:
  PatchMapOptions options_;
  PointCloud fused_;
  std::unique_ptr<PointCloudTree> tree_;
  int keyframes_ = 0;
};

}  // namespace pg
