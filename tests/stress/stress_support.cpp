#include "stress_support.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>

#include "pg/sim/scene.h"

namespace pg::stress {

bool long_cases_enabled() {
#ifdef PG_STRESS_LONG
  return true;
#else
  const char* env = std::getenv("PG_STRESS_LONG");
  return env != nullptr && std::strcmp(env, "") != 0 && std::strcmp(env, "0") != 0;
#endif
}

bool all_finite(const ImageF& image) {
  return std::all_of(image.data.begin(), image.data.end(),
                     [](float v) { return std::isfinite(v); });
}

bool all_finite(const PointCloud& cloud) {
  auto finite = [](const Eigen::Vector3f& v) { return v.allFinite(); };
  return std::all_of(cloud.points.begin(), cloud.points.end(), finite) &&
         std::all_of(cloud.normals.begin(), cloud.normals.end(), finite);
}

std::vector<SE3> default_cube_loop() {
  const Scene scene = load_scene(std::string(PG_SOURCE_DIR) + "/scenes/default.json");
  std::vector<SE3> poses;
  for (int f = 0; f < 60; ++f) poses.push_back(scene.objects.at(0).T_world_object.at(f));
  return poses;
}

std::vector<SE3> cube_rocking(int frames) {
  static const std::vector<SE3> loop = default_cube_loop();
  std::vector<SE3> poses;
  for (int f = 0; f < frames; ++f) poses.push_back(loop[f % loop.size()]);
  return poses;
}

SE3 shifted(const SE3& T_sensor_object, const Eigen::Vector3d& offset_sensor) {
  return SE3::Translation(offset_sensor) * T_sensor_object;
}

namespace {

// This thread's CPU time: unlike the wall clock, it does not count the time other jobs on the
// machine take (with one oneTBB thread, all of the tracker's work runs on this thread).
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

// Index of the first frame of the last contact episode.
std::size_t last_episode_start(const std::vector<StressFrame>& frames) {
  for (std::size_t i = frames.size(); i-- > 0;) {
    if (frames[i].estimate.new_episode) return i;
  }
  return 0;
}

}  // namespace

double StressRun::last_episode_max_translation_m(int skip) const {
  double worst = 0;
  for (std::size_t i = last_episode_start(frames) + skip; i < frames.size(); ++i) {
    if (frames[i].estimate.contact) worst = std::max(worst, frames[i].translation_error_m);
  }
  return worst;
}

double StressRun::last_episode_max_rotation_rad(int skip) const {
  double worst = 0;
  for (std::size_t i = last_episode_start(frames) + skip; i < frames.size(); ++i) {
    if (frames[i].estimate.contact) worst = std::max(worst, frames[i].rotation_error_rad);
  }
  return worst;
}

double StressRun::max_translation_error_m() const {
  double worst = 0;
  for (const auto& f : frames) worst = std::max(worst, f.translation_error_m);
  return worst;
}

void StressRun::print(const std::string& name) const {
  double max_r = 0;
  for (const auto& f : frames) max_r = std::max(max_r, f.rotation_error_rad);
  std::printf(
      "[stress] %s: %zu frames, %d contact, %d episodes, lost %d, rejected %d, "
      "unconverged %d, overridden %d; max error %.3f mm %.4f rad, final %.3f mm %.4f rad, "
      "last episode max %.3f mm\n",
      name.c_str(), frames.size(), contact_frames, episodes, lost_frames, rejected_registrations,
      unconverged_registrations, overridden_registrations, max_translation_error_m() * 1e3, max_r,
      last().translation_error_m * 1e3, last().rotation_error_rad,
      last_episode_max_translation_m() * 1e3);
}

ClosedLoop::ClosedLoop(std::shared_ptr<const ObjectShape> shape, const std::string& preset)
    : case_(test::make_render_case(preset, std::move(shape))) {}

ImageF ClosedLoop::normals(const SE3& T_sensor_object) const {
  return test::render(case_, T_sensor_object).images.normal;
}

StressRun ClosedLoop::track(const std::vector<SE3>& T_sensor_object, const GraphOptions& options,
                            const StressHooks& hooks) const {
  PatchGraphTracker tracker(options);
  ContactCloudBuilder builder(case_.sensor, ContactCloudOptions());
  ContactFrame contact;
  StressRun run;
  RenderedFrame rendered;
  for (std::size_t i = 0; i < T_sensor_object.size(); ++i) {
    const SE3& truth = T_sensor_object[i];
    case_.renderer->render({truth}, 0, rendered);
    ImageF& image = rendered.images.normal;
    if (hooks.corrupt_normals) {
      rendered.filled = {};  // the hook edits pixels in place: the next frame renders afresh
      hooks.corrupt_normals(int(i), image);
    }
    const double start_ms = thread_cpu_ms();
    builder.build(image, contact);
    TrackerInput input;
    input.T_world_sensor_measured = SE3();
    input.T_world_object_prior = truth;
    set_measurement(contact, input);
    if (hooks.corrupt_input) hooks.corrupt_input(int(i), input);
    StressFrame f;
    f.cloud_points = int(input.cloud_sensor.size());
    f.rejected_normals = contact.rejected_normals;
    f.estimate = tracker.add(input);
    f.frame_ms = thread_cpu_ms() - start_ms;
    f.T_world_object_gt = truth;
    f.finite = is_finite(f.estimate.T_world_object) && is_finite(f.estimate.T_world_sensor);
    f.translation_error_m = translation_distance(f.estimate.T_world_object, truth);
    f.rotation_error_rad = rotation_distance(f.estimate.T_world_object, truth);
    run.contact_frames += f.estimate.contact;
    run.episodes += f.estimate.new_episode;
    run.lost_frames += f.estimate.tracking_lost;
    run.rejected_registrations += f.estimate.rejected_registrations;
    run.unconverged_registrations += f.estimate.unconverged_registrations;
    run.overridden_registrations += f.estimate.overridden_registrations;
    if (!f.finite && run.all_finite) {
      run.all_finite = false;
      run.first_non_finite = int(i);
    }
    run.frames.push_back(f);
  }
  return run;
}

const ClosedLoop& cube_loop() {
  static const ClosedLoop loop(test::mesh_shape("cube.glb"));
  return loop;
}

}  // namespace pg::stress
