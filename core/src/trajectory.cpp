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

namespace {

// Each pose's quaternion on the same side as the one before (q and -q are one rotation): the
// poses written frame by frame then run on without a sign jump where a waypoint's rpy gives the
// other sign (yaw 3.1 then -3.1: the slerp between took the short way, the waypoint itself had
// come out negated).
void align_signs(std::vector<SE3>& poses) {
  for (std::size_t i = 1; i < poses.size(); ++i) {
    if (poses[i].rotation().dot(poses[i - 1].rotation()) >= 0.0) continue;
    Eigen::Quaterniond q = poses[i].rotation();
    q.coeffs() = -q.coeffs();
    poses[i] = SE3(q, poses[i].translation());
  }
}

}  // namespace

Trajectory Trajectory::from_waypoints(const std::vector<Waypoint>& waypoints) {
  assert(!waypoints.empty());
  Trajectory t;
  for (const auto& w : waypoints) {
    assert(t.frames_.empty() || w.frame > t.frames_.back());
    t.frames_.push_back(w.frame);
    t.poses_.push_back(pose_from_position_rpy(w.position_m, w.rpy_rad));
  }
  align_signs(t.poses_);
  return t;
}

Trajectory Trajectory::from_poses(const std::vector<SE3>& poses) {
  assert(!poses.empty());
  Trajectory t;
  t.poses_ = poses;
  align_signs(t.poses_);
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
