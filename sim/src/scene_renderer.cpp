#include "pg/sim/scene_renderer.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <mutex>

#include "pg/core/error.h"
#include "shading.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

RenderSettings settings_for(const SceneRender& render, const std::vector<std::string>& outputs) {
  RenderSettings s;
  auto wants = [&](const char* name) {
    return std::find(outputs.begin(), outputs.end(), name) != outputs.end();
  };
  s.color = wants("color");
  s.normal = wants("normal");
  s.depth = wants("depth");
  s.mask = wants("mask");
  s.contact_points = wants("points");
  s.noise = render.noise;
  s.shadows = render.shadows;
  s.background = render.background;
  return s;
}

}  // namespace

SceneRenderer::SceneRenderer(Scene scene, const RenderOverrides& overrides)
    : scene_(std::move(scene)) {
  if (!overrides.outputs.empty()) scene_.render.outputs = overrides.outputs;
  if (!overrides.background.empty()) scene_.render.background = overrides.background;
  if (overrides.shadows) scene_.render.shadows = *overrides.shadows;
  if (overrides.elastic) {
    for (auto& sensor : scene_.sensors) sensor.model.gel.elastic.enabled = *overrides.elastic;
  }
  for (auto& sensor : scene_.sensors) {
    if (overrides.width > 0 || overrides.height > 0) {
      const auto& cam = sensor.model.camera;
      sensor.model.camera = cam.resized(overrides.width > 0 ? overrides.width : cam.width,
                                        overrides.height > 0 ? overrides.height : cam.height);
    }
  }
  for (std::size_t i = 0; i < scene_.objects.size(); ++i) {
    const SceneObject& object = scene_.objects[i];
    try {
      shapes_.push_back(std::make_shared<ObjectShape>(load_mesh(object.mesh_path, object.scale)));
    } catch (const InputError& e) {  // the mesh file's own error, and where the scene names it
      throw InputError(scene_.path + ": objects[" + std::to_string(i) + "].mesh: " + e.what());
    }
  }
  if (!scene_.render.background.empty() && !fs::exists(scene_.render.background)) {
    const std::string where = overrides.background.empty()
                                  ? scene_.path + ": render.background"
                                  : std::string("background given for the scene");
    throw InputError(where + ": " + scene_.render.background +
                     ": no such image file (give an image, or synthetic or none)");
  }
  const RenderSettings settings = settings_for(scene_.render, scene_.render.outputs);
  for (const auto& sensor : scene_.sensors) {
    sensors_.push_back(std::make_unique<SensorRenderer>(sensor.model, shapes_, settings));
  }
}

std::vector<SE3> SceneRenderer::object_poses_in_sensor(int sensor, int frame) const {
  const SE3 T_sensor_world = scene_.sensors[sensor].T_world_sensor.at(frame).inverse();
  std::vector<SE3> poses;
  for (const auto& object : scene_.objects) {
    poses.push_back(T_sensor_world * object.T_world_object.at(frame));
  }
  return poses;
}

std::uint64_t SceneRenderer::noise_seed(int sensor, int frame) const {
  return splitmix64(splitmix64(scene_.render.seed ^ (std::uint64_t(sensor) << 40)) + frame);
}

std::vector<RenderedFrame> SceneRenderer::render_frame(int frame) const {
  std::vector<RenderedFrame> out;
  for (int i = 0; i < sensor_count(); ++i) {
    out.push_back(sensors_[i]->render(object_poses_in_sensor(i, frame), noise_seed(i, frame)));
  }
  return out;
}

RenderSummary render_scene_to_dataset(const SceneRenderer& renderer, const std::string& out_dir,
                                      const ProgressFn& progress) {
  const Scene& scene = renderer.scene();
  const SceneObject& tracked = scene.objects[scene.tracked_object];
  RenderSummary summary;
  summary.frames = scene.frames;
  std::vector<std::string> dirs;
  for (int i = 0; i < renderer.sensor_count(); ++i) {
    dirs.push_back(renderer.sensor_count() == 1
                       ? out_dir
                       : (fs::path(out_dir) / scene.sensors[i].name).string());
  }
  // Every folder is checked before any is written: a refused second one must not leave the first
  // half replaced.
  if (renderer.sensor_count() > 1 && fs::exists(fs::path(out_dir) / "dataset.json")) {
    throw InputError(out_dir + ": holds a dataset; a scene of " +
                     std::to_string(renderer.sensor_count()) +
                     " sensors writes one dataset per sensor into their own folders under a new "
                     "or empty folder");
  }
  for (const auto& dir : dirs) DatasetWriter::check_folder(dir);
  std::vector<std::unique_ptr<DatasetWriter>> writers;
  for (int i = 0; i < renderer.sensor_count(); ++i) {
    DatasetInfo info;
    info.sensor = renderer.sensor(i).sensor();
    // dataset.json describes the frames: a scene rendered without noise has none, whatever its
    // sensor's noise model would add.
    if (!scene.render.noise) info.sensor.noise.sigma = 0.0;
    info.frames = scene.frames;
    info.fps = scene.fps;
    info.outputs = scene.render.outputs;
    info.scene = fs::absolute(scene.path).lexically_normal().string();
    info.seed = scene.render.seed;
    info.object_name = tracked.name;
    info.object_mesh = fs::absolute(tracked.mesh_path).lexically_normal().string();
    info.object_scale = tracked.scale;
    const std::string& dir = dirs[i];
    writers.push_back(std::make_unique<DatasetWriter>(dir, info));
    if (info.has_output("color"))
      writers.back()->write_background(renderer.sensor(i).background_color_u8());
    summary.dataset_dirs.push_back(dir);
  }
  std::atomic<int> done{0}, contact_frames{0}, clamped_frames{0};
  std::mutex progress_mutex;
  const auto start = std::chrono::steady_clock::now();
  tbb::parallel_for(0, scene.frames, [&](int frame) {
    const auto frames = renderer.render_frame(frame);
    bool contact = false, clamped = false;
    for (int i = 0; i < renderer.sensor_count(); ++i) {
      FramePose pose;
      pose.frame = frame;
      pose.time_s = frame / scene.fps;
      pose.T_world_object = tracked.T_world_object.at(frame);
      pose.T_world_sensor = scene.sensors[i].T_world_sensor.at(frame);
      pose.contact = frames[i].stats.contact;
      FrameImages images = frames[i].images;
      if (!frames[i].contact_points_object.empty()) {
        images.contact_points = frames[i].contact_points_object[scene.tracked_object];
      }
      writers[i]->write_frame(pose, images);
      contact = contact || frames[i].stats.contact;
      clamped = clamped || frames[i].stats.clamped_pixels > 0;
    }
    contact_frames += contact;
    clamped_frames += clamped;
    const int n = ++done;
    if (progress) {
      std::lock_guard<std::mutex> lock(progress_mutex);
      progress(n, scene.frames);
    }
  });
  for (auto& w : writers) w->finish();
  if (renderer.sensor_count() > 1) {
    std::vector<std::string> names;
    for (const auto& sensor : scene.sensors) names.push_back(sensor.name);
    write_sensor_index(out_dir, names);
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summary.contact_frames = contact_frames;
  summary.clamped_frames = clamped_frames;
  return summary;
}

}  // namespace pg
