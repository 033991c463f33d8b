#include "pg/core/trajectory.h"

#include <algorithm>
#include <cassert>

namespace pg {

Trajectory Trajectory::constant(const SE3& pose) {
  Trajectory t;
  t.frames_ = {0};
  t.poses_ = {pose};
  return t;
}

Trajectory Trajectory::from_waypoints(const std::vector<Waypoint>& waypoints) {
  assert(!waypoints.empty());
  Trajectory t;
  for (const auto& w : waypoints) {
    assert(t.frames_.empty() || w.frame > t.frames_.back());
    t.frames_.push_back(w.frame);
    t.poses_.push_back(pose_from_position_rpy(w.position_m, w.rpy_rad));
  }
  return t;
}

Trajectory Trajectory::from_poses(const std::vector<SE3>& poses) {
  assert(!poses.empty());
  Trajectory t;
  t.poses_ = poses;
  t.per_frame_ = true;
  return t;
}

Trajectory Trajectory::carried_by(const Trajectory& parent) const {
  Trajectory t = *this;
  t.parent_ = std::make_shared<const Trajectory>(parent);
  return t;
}

SE3 Trajectory::at(int frame) const {
  return parent_ ? parent_->at(frame) * own_at(frame) : own_at(frame);
}

SE3 Trajectory::own_at(int frame) const {
  if (poses_.empty()) return SE3::Identity();
  if (per_frame_) {
    return poses_[std::clamp<std::size_t>(std::max(frame, 0), 0, poses_.size() - 1)];
  }
  if (frame <= frames_.front()) return poses_.front();
  if (frame >= frames_.back()) return poses_.back();
  const auto next = std::upper_bound(frames_.begin(), frames_.end(), frame) - frames_.begin();
  const auto prev = next - 1;
  // In double: waypoints a billion frames either side of 0 would overflow int differences.
  const double s =
      (double(frame) - double(frames_[prev])) / (double(frames_[next]) - double(frames_[prev]));
  return interpolate(poses_[prev], poses_[next], s);
}

}  // namespace pg
