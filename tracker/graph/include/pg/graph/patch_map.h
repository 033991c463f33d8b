#pragma once
// The local patch (paper section IV-C): key-frame clouds fused in the object frame with the
// estimates current when each was added (or moved later to revised ones), averaged per voxel,
// with a k-d tree for registration.
// Reset at every new contact episode. For the GroundtruthPatch baseline it holds a fixed model.
#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <vector>

#include "pg/tracker/kd_tree.h"
#include "pg/tracker/point_cloud.h"

namespace pg {

struct PatchMapOptions {
  int keyframe_interval = 10;  // frames between key frames (the reference code: 10 sim, 5 real)
  // Voxel edge of the fused patch [m]: each voxel of a grid fixed in the object frame holds the
  // mean of every key-frame point that fell in it; 0 keeps every point.
  double voxel_m = 1e-4;
  // Frames after which a key frame's cloud is taken out of the patch and fused again with the
  // pose the fixed-lag window has settled on for it since (it was first fused with the estimate
  // of the newest frame, which the window's later solves revise); 0 leaves it where it was
  // fused. The window solves a frame for the last time window - 1 frames after it, where the
  // tracker caps this (beyond it the pose no longer changes).
  // Off by default: on the benchmark it lowers the cube's rotation RMSE (0.93x over three noise
  // seeds) but lifts the median final rotation of the toy brick, which the targets read
  // (docs/tracker.md, "Key frames settled").
  int keyframe_settle_frames = 0;
};

class PatchMap {
 public:
  explicit PatchMap(PatchMapOptions options = {}) : options_(options) {}

  void reset();
  // Moves a key frame's cloud into the object frame and fuses it; rebuilds the tree. Returns the
  // key frame's number (0 for the first since the reset). With `movable` the patch keeps the
  // cloud so that move_keyframe can place it again. Throws std::invalid_argument for a cloud
  // without a normal for each point, or a point, normal or pose that is not finite.
  int add_keyframe(const PointCloud& cloud_sensor, const SE3& T_object_sensor,
                   bool movable = false);
  // Takes movable key frame `keyframe`'s points out of the patch and fuses them again at
  // T_object_sensor; rebuilds the tree. The key frame is no longer movable after. Throws
  // std::invalid_argument if `keyframe` is not a movable key frame of this patch.
  void move_keyframe(int keyframe, const SE3& T_object_sensor);
  // A fixed model (object frame, built as its tree) instead of key frames: the GroundtruthPatch
  // baseline. The tree is shared, not copied: every sensor's patch and every run of one object may
  // hold the same one.
  void set_model(std::shared_ptr<const PointCloudTree> model_object);
  // The model set_model gave; null for a patch of key frames.
  const std::shared_ptr<const PointCloudTree>& model() const { return model_; }
  // A model patch fuses no key frames: each marks the cells (of edge kTouchedCellM, on a grid
  // fixed in the object frame) that its cloud lies in at T_object_sensor. Marks add up until
  // reset or set_model. Throws std::logic_error on a patch without a model.
  void mark_touched(const PointCloud& cloud_sensor, const SE3& T_object_sensor);
  // What patch.ply holds: the fused key frames; of a model, the part that was touched (its
  // points in the marked cells and their neighbours), not the whole sampled surface.
  PointCloud exported() const;
  static constexpr double kTouchedCellM = 2.5e-4;

  bool empty() const { return !tree_; }
  // Throws std::logic_error on an empty patch (no key frame or model yet).
  const PointCloudTree& tree() const {
    if (!tree_) throw std::logic_error("PatchMap::tree: the patch is empty");
    return *tree_;
  }
  const PointCloud& cloud_object() const { return model_ ? model_->cloud() : fused_; }
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
  // A voxel's cell on the grid; a point that has none (voxel_m 0, or coordinates past the
  // grid's range) is a cell of its own, numbered past any real one.
  using VoxelKey = std::array<std::int64_t, 3>;
  // A key frame that move_keyframe may still place elsewhere: what it fused, and where.
  struct MovableKeyframe {
    int keyframe;
    PointCloud cloud_sensor;
    SE3 T_object_sensor;
    std::vector<VoxelKey> keys;  // each point's voxel
  };
  // Adds each point of the cloud at T to its voxel's sums and returns the voxels used, or with
  // `remove` takes each out of the voxel recorded when it was added (and returns none).
  std::vector<VoxelKey> accumulate(const PointCloud& cloud_sensor, const SE3& T_object_sensor,
                                   const std::vector<VoxelKey>* remove = nullptr);
  void rebuild();  // the fused cloud and its tree from the voxels' sums

  std::map<VoxelKey, VoxelSum> voxels_;  // ordered: a deterministic patch
  PatchMapOptions options_;
  PointCloud fused_;
  std::shared_ptr<const PointCloudTree> tree_;  // fused_'s, or the model's
  std::shared_ptr<const PointCloudTree> model_;
  int keyframes_ = 0;
  std::int64_t next_own_cell_ = 0;  // numbers the cells of points without one
  std::set<VoxelKey> touched_;      // a model's cells marked by mark_touched
  std::vector<MovableKeyframe> movable_;
};

}  // namespace pg
