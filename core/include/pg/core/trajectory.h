#pragma once
// A pose per frame: constant, from waypoints (linear in position, slerp in rotation, as the
// reference data was generated), or an explicit per-frame list.
#include <memory>
#include <vector>

#include "pg/core/se3.h"

namespace pg {

struct Waypoint {
  int frame = 0;
  Eigen::Vector3d position_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d rpy_rad = Eigen::Vector3d::Zero();  // see quaternion_from_rpy
};

class Trajectory {
 public:
  Trajectory() = default;  // identity everywhere
  static Trajectory constant(const SE3& pose);
  // Waypoints must have strictly increasing frames (asserted by the scene loader). Before the
  // first waypoint the pose holds at the first, after the last at the last.
  static Trajectory from_waypoints(const std::vector<Waypoint>& waypoints);
  // Frame i takes poses[i]; frames past the end hold the last pose.
  static Trajectory from_poses(const std::vector<SE3>& poses);

  // This trajectory taken as relative to a moving frame: at(f) = parent.at(f) * this->at(f)
  // (an object held by a sensor, its poses given in the sensor's frame).
  Trajectory carried_by(const Trajectory& parent) const;

  SE3 at(int frame) const;

 private:
  SE3 own_at(int frame) const;

  std::vector<int> frames_;
  std::vector<SE3> poses_;
  bool per_frame_ = false;
  std::shared_ptr<const Trajectory> parent_;
};

}  // namespace pg
