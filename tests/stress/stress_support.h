#pragma once
// The stress suite's closed loop in memory: render an object's poses over a fixed sensor into
// normal images, build the contact clouds, track them with PatchGraph, and keep what each frame
// reported. No files: a case costs what the renderer and the tracker cost.
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "../tracker/tracker_test_util.h"
#include "pg/graph/tracker.h"
#include "pg/tracker/contact_cloud.h"

namespace pg::stress {

// Long cases (the 10,000-frame sequence) run when the build sets PG_STRESS_LONG (CMake option
// PG_STRESS_LONG=ON) or the environment has PG_STRESS_LONG=1.
bool long_cases_enabled();

bool all_finite(const ImageF& image);
bool all_finite(const PointCloud& cloud);

// The object's pose in S for frames 0..59 of scenes/default.json: a cube corner rocking in a
// loop (the pose at frame 60 equals frame 0), the sequence the tracker tests know it tracks.
std::vector<SE3> default_cube_loop();
// `frames` frames of the loop, repeated.
std::vector<SE3> cube_rocking(int frames);
// The pose moved by `offset_sensor` along S (e.g. lifted off the gel by +z).
SE3 shifted(const SE3& T_sensor_object, const Eigen::Vector3d& offset_sensor);

struct StressFrame {
  TrackerEstimate estimate;
  SE3 T_world_object_gt;
  double translation_error_m = 0;
  double rotation_error_rad = 0;
  bool finite = false;  // the estimate's poses are finite
  int cloud_points = 0;
  int rejected_normals = 0;
  double frame_ms = 0;  // front end + tracker update, this thread's CPU time
};

struct StressRun {
  std::vector<StressFrame> frames;
  int contact_frames = 0;
  int episodes = 0;
  int lost_frames = 0;
  int rejected_registrations = 0;
  int unconverged_registrations = 0;
  int overridden_registrations = 0;
  bool all_finite = true;
  int first_non_finite = -1;
  // The largest error over the contact frames of the last episode (frames from its start + skip).
  double last_episode_max_translation_m(int skip = 0) const;
  double last_episode_max_rotation_rad(int skip = 0) const;
  double max_translation_error_m() const;
  const StressFrame& last() const { return frames.back(); }
  // One line for the docs' table (docs/stress.md): counts and errors, prefixed "[stress] name".
  void print(const std::string& name) const;
};

// Hooks a case may set to corrupt what the tracker sees.
struct StressHooks {
  // Edits frame i's normal image before the front end sees it.
  std::function<void(int, ImageF&)> corrupt_normals;
  // Edits frame i's tracker input (poses, cloud) before the tracker sees it.
  std::function<void(int, TrackerInput&)> corrupt_input;
};

// One object over a DIGIT (rigid gel, no noise: tracker_test_util's render case) at the world
// origin; the object's poses in S are the world poses.
class ClosedLoop {
 public:
  ClosedLoop(std::shared_ptr<const ObjectShape> shape, const std::string& preset = "digit");

  const test::RenderCase& render_case() const { return case_; }
  ImageF normals(const SE3& T_sensor_object) const;

  // Renders each frame when the tracker needs it (long sequences are not held in memory) and
  // tracks the poses; the sensor pose is measured exactly and the vision prior is the truth
  // (hooks.corrupt_input perturbs either).
  StressRun track(const std::vector<SE3>& T_sensor_object, const GraphOptions& options = {},
                  const StressHooks& hooks = {}) const;

 private:
  test::RenderCase case_;
};

// The 20 mm cube (meshes/cube.glb) over the DIGIT, made once.
const ClosedLoop& cube_loop();

}  // namespace pg::stress
