#include "pg/graph/patch_map.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace pg {
namespace {

// Cell indices past this (a cell edge 1e-15 of the coordinates) would overflow.
constexpr double kMaxCell = 1e15;

// The cell of the grid of edge 1 / inv that holds p; false where there is none (inv 0, or an
// index past kMaxCell).
bool cell_of(const Eigen::Vector3d& p, double inv, std::array<std::int64_t, 3>& key) {
  const Eigen::Vector3d cell = (p * inv).array().floor();
  if (!(inv > 0 && cell.cwiseAbs().maxCoeff() < kMaxCell)) return false;
  key = {std::int64_t(cell.x()), std::int64_t(cell.y()), std::int64_t(cell.z())};
  return true;
}

}  // namespace

void PatchMap::reset() {
  voxels_.clear();
  fused_.clear();
  tree_.reset();
  model_.reset();
  touched_.clear();
  keyframes_ = 0;
  next_own_cell_ = 0;
  movable_.clear();
}

namespace {

// A key frame's cloud and pose as the patch can fuse them: a normal for every point (the
// registrations' target needs them) and nothing non-finite (one NaN point had sent the patch's
// tree's nearest neighbours astray).
void check_pose(const SE3& T, const char* what) {
  if (!is_finite(T)) throw std::invalid_argument(std::string(what) + ": the pose is not finite");
}

void check_keyframe(const PointCloud& cloud, const SE3& T, const char* what) {
  if (cloud.normals.size() != cloud.points.size()) {
    throw std::invalid_argument(std::string(what) + ": the cloud has " +
                                std::to_string(cloud.points.size()) + " points and " +
                                std::to_string(cloud.normals.size()) +
                                " normals; the patch needs one normal a point");
  }
  check_pose(T, what);
  for (std::size_t i = 0; i < cloud.points.size(); ++i) {
    if (!cloud.points[i].allFinite() || !cloud.normals[i].allFinite()) {
      throw std::invalid_argument(std::string(what) + ": point " + std::to_string(i) +
                                  " or its normal is not finite");
    }
  }
}

}  // namespace

int PatchMap::add_keyframe(const PointCloud& cloud_sensor, const SE3& T_object_sensor,
                           bool movable) {
  check_keyframe(cloud_sensor, T_object_sensor, "PatchMap::add_keyframe");
  std::vector<VoxelKey> keys = accumulate(cloud_sensor, T_object_sensor);
  if (movable) movable_.push_back({keyframes_, cloud_sensor, T_object_sensor, std::move(keys)});
  rebuild();
  return keyframes_++;
}

void PatchMap::move_keyframe(int keyframe, const SE3& T_object_sensor) {
  const auto it = std::find_if(movable_.begin(), movable_.end(),
                               [&](const MovableKeyframe& m) { return m.keyframe == keyframe; });
  if (it == movable_.end()) {
    throw std::invalid_argument("PatchMap::move_keyframe: key frame " + std::to_string(keyframe) +
                                " is not a movable key frame of this patch");
  }
  check_pose(T_object_sensor, "PatchMap::move_keyframe");
  accumulate(it->cloud_sensor, it->T_object_sensor, &it->keys);
  accumulate(it->cloud_sensor, T_object_sensor);
  movable_.erase(it);
  rebuild();
}

std::vector<PatchMap::VoxelKey> PatchMap::accumulate(const PointCloud& cloud_sensor,
                                                     const SE3& T_object_sensor,
                                                     const std::vector<VoxelKey>* remove) {
  // Taking a key frame out repeats the transform it was added with, so each point subtracts
  // exactly the values it added, from the voxel it went to.
  const PointCloud moved = transform_cloud(T_object_sensor, cloud_sensor);
  const double inv = options_.voxel_m > 0 ? 1.0 / options_.voxel_m : 0.0;
  const double sign = remove ? -1.0 : 1.0;
  std::vector<VoxelKey> keys;  // of the points added (a removal reads them from `remove`)
  if (!remove) keys.resize(moved.size());
  for (std::size_t i = 0; i < moved.size(); ++i) {
    const Eigen::Vector3d p = moved.points[i].cast<double>();
    // A point without a cell (every point when voxel_m is 0) keeps one of its own, numbered
    // past any real one.
    if (!remove && !cell_of(p, inv, keys[i])) {
      keys[i] = VoxelKey{std::int64_t(kMaxCell) + next_own_cell_++, 0, 0};
    }
    const auto v = voxels_.try_emplace(remove ? (*remove)[i] : keys[i]).first;
    v->second.point_sum += sign * p;
    v->second.normal_sum += sign * moved.normals[i].cast<double>();
    v->second.count += remove ? -1 : 1;
    if (v->second.count == 0) voxels_.erase(v);
  }
  return keys;
}

void PatchMap::rebuild() {
  fused_.clear();
  fused_.reserve(voxels_.size());
  for (const auto& [key, v] : voxels_) {
    const double len = v.normal_sum.norm();
    if (!(len > 0)) continue;  // opposite normals cancelled: no plane to register against
    fused_.push_back((v.point_sum / v.count).cast<float>(),
                     Eigen::Vector3f((v.normal_sum / len).cast<float>()));
  }
  tree_ = std::make_shared<const PointCloudTree>(fused_);
}

void PatchMap::mark_touched(const PointCloud& cloud_sensor, const SE3& T_object_sensor) {
  if (!model_) throw std::logic_error("PatchMap::mark_touched: the patch has no model");
  const PointCloud moved = transform_cloud(T_object_sensor, cloud_sensor);
  VoxelKey key{}, last{};
  for (std::size_t i = 0; i < moved.size(); ++i) {
    // Neighbouring pixels mostly share a cell: each is looked up once per run of them.
    if (cell_of(moved.points[i].cast<double>(), 1.0 / kTouchedCellM, key) &&
        (i == 0 || key != last)) {
      touched_.insert(key);
    }
    last = key;
  }
}

PointCloud PatchMap::exported() const {
  if (!model_) return fused_;
  // The marked cells and their neighbours: every model point within a cell's edge of a touched
  // point is kept (a surface that only grazes a marked point's cell leaves no holes), none more
  // than two cells' diagonal from one.
  std::set<VoxelKey> near;
  for (const VoxelKey& c : touched_) {
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy)
        for (std::int64_t dz = -1; dz <= 1; ++dz) near.insert({c[0] + dx, c[1] + dy, c[2] + dz});
  }
  PointCloud part;
  const PointCloud& model = model_->cloud();
  VoxelKey key{};
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (cell_of(model.points[i].cast<double>(), 1.0 / kTouchedCellM, key) && near.count(key))
      part.push_back(model.points[i], model.normals[i]);
  }
  return part;
}

void PatchMap::set_model(std::shared_ptr<const PointCloudTree> model_object) {
  if (!model_object) throw std::invalid_argument("PatchMap::set_model: no model");
  voxels_.clear();
  movable_.clear();
  fused_.clear();
  touched_.clear();
  model_ = std::move(model_object);
  tree_ = model_;
  keyframes_ = 0;
}

}  // namespace pg
