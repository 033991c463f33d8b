#include "pg/sim/scene_renderer.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>

#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/image.h"
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
  s.normal = wants("normal") || wants("normal_png");
  s.depth = wants("depth");
  s.mask = wants("mask");
  s.contact_points = wants("points");
  s.noise = render.noise;
  s.shadows = render.shadows;
  s.background = render.background;
  return s;
}

// The pixels of all of a scene's sensors.
std::uintmax_t sensor_pixels(const Scene& scene) {
  std::uintmax_t pixels = 0;
  for (const auto& sensor : scene.sensors) {
    pixels +=
        std::uintmax_t(sensor.model.camera.width) * std::uintmax_t(sensor.model.camera.height);
  }
  return pixels;
}

// The memory the system can still give (/proc/meminfo's MemAvailable); nullopt where it does not
// say.
std::optional<std::uintmax_t> available_memory_bytes() {
  std::ifstream meminfo("/proc/meminfo");
  std::string key, unit;
  std::uintmax_t kb = 0;
  while (meminfo >> key >> kb >> unit) {
    if (key == "MemAvailable:") return kb * 1024;
  }
  return std::nullopt;
}

std::string size_text(std::uintmax_t bytes) {
  char text[32];
  if (bytes >= 1'000'000'000'000) {
    std::snprintf(text, sizeof text, "%.1f TB", bytes / 1e12);
  } else if (bytes >= 1'000'000'000) {
    std::snprintf(text, sizeof text, "%.1f GB", bytes / 1e9);
  } else if (bytes >= 1'000'000) {
    std::snprintf(text, sizeof text, "%.1f MB", bytes / 1e6);
  } else if (bytes >= 1'000) {
    std::snprintf(text, sizeof text, "%.1f kB", bytes / 1e3);
  } else {
    std::snprintf(text, sizeof text, "%ju bytes", std::uintmax_t(bytes));
  }
  return text;
}

}  // namespace

SceneRenderer::SceneRenderer(Scene scene, const RenderOverrides& overrides)
    : scene_(std::move(scene)) {
  // What a scene file and tacsim's options could not give, set in C++: an output of another name
  // (a typo had rendered every image empty), a negative size or frame count (ignored), a tracked
  // object past the list (read out of bounds when the dataset was described).
  const std::vector<std::string>& known = dataset_output_names();
  for (const std::string& name : overrides.outputs) {
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      std::string list;
      for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
      throw InputError("RenderOverrides: unknown output '" + name + "' (known: " + list + ")");
    }
  }
  if (overrides.width < 0 || overrides.height < 0 || overrides.frames < 0) {
    throw InputError("RenderOverrides: width " + std::to_string(overrides.width) + ", height " +
                     std::to_string(overrides.height) + ", frames " +
                     std::to_string(overrides.frames) + "; none may be negative (0: the scene's)");
  }
  if (scene_.tracked_object < 0 || std::size_t(scene_.tracked_object) >= scene_.objects.size()) {
    throw InputError(scene_.path + ": tracked_object " + std::to_string(scene_.tracked_object) +
                     " is not one of its " + std::to_string(scene_.objects.size()) + " objects");
  }
  if (overrides.frames > scene_.frames) {
    throw InputError(scene_.path + ": has " + std::to_string(scene_.frames) +
                     " frames, fewer than the " + std::to_string(overrides.frames) + " asked for");
  }
  if (overrides.frames > 0) scene_.frames = overrides.frames;
  if (!overrides.outputs.empty()) scene_.render.outputs = overrides.outputs;
  // The words a scene's render.background takes mean the same given on the command line.
  if (names_synthetic_background(overrides.background)) {
    scene_.render.background.clear();
  } else if (!overrides.background.empty()) {
    scene_.render.background = overrides.background;
  }
  if (overrides.shadows) scene_.render.shadows = *overrides.shadows;
  if (overrides.noise) scene_.render.noise = *overrides.noise;
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
  // The renderer's own buffers and a frame's images must fit the memory the machine has left:
  // refused now, before they are made (at 8192 x 8192 px, 8 GB of them a sensor, minutes of it),
  // rather than killed later with nothing said.
  const std::uintmax_t pixels = sensor_pixels(scene_);
  const std::uintmax_t needed = pixels * (kRendererBytesPerPixel + kFrameBytesPerPixel);
  if (const auto memory = available_memory_bytes(); memory && needed > *memory) {
    throw InputError(scene_.path + ": rendering " + std::to_string(scene_.sensors.size()) +
                     " sensor(s) of " + std::to_string(pixels) + " px in all needs about " +
                     size_text(needed) + " of memory and the machine has " + size_text(*memory) +
                     " available; render smaller images (--width, --height)");
  }
  // A mesh file at one scale is loaded (and repaired, and warned about) once, however many
  // objects use it: the shapes are geometry only, shared by the objects' poses.
  std::map<std::pair<std::string, double>, std::shared_ptr<ObjectShape>> loaded;
  for (std::size_t i = 0; i < scene_.objects.size(); ++i) {
    const SceneObject& object = scene_.objects[i];
    std::shared_ptr<ObjectShape>& shape = loaded[{object.mesh_path, object.scale}];
    try {
      if (!shape) shape = std::make_shared<ObjectShape>(load_mesh(object.mesh_path, object.scale));
    } catch (const InputError& e) {  // the mesh file's own error, and where the scene names it
      throw InputError(scene_.path + ": objects[" + std::to_string(i) + "].mesh: " + e.what());
    }
    shapes_.push_back(shape);
  }
  const std::string& background = scene_.render.background;
  const std::string background_where = overrides.background.empty()
                                           ? scene_.path + ": render.background"
                                           : std::string("background given for the scene");
  if (!background.empty() && !fs::exists(background)) {
    throw InputError(background_where + ": " + background +
                     ": no such image file (give an image, or synthetic or none)");
  }
  const RenderSettings settings = settings_for(scene_.render, scene_.render.outputs);
  for (const auto& sensor : scene_.sensors) {
    try {
      sensors_.push_back(std::make_unique<SensorRenderer>(sensor.model, shapes_, settings));
    } catch (const InputError& e) {  // the background image's own error, and where it was given
      const std::string what = e.what();
      if (background.empty() || what.rfind(background, 0) != 0) throw;
      throw InputError(background_where + ": " + what);
    }
  }
}

std::vector<SE3> SceneRenderer::object_poses_in_sensor(int sensor, int frame) const {
  // A frame past the scene's had rendered its first or last pose without a word.
  if (frame < 0 || frame >= scene_.frames) {
    throw std::out_of_range("SceneRenderer: frame " + std::to_string(frame) + " of a scene of " +
                            std::to_string(scene_.frames) + " frames");
  }
  const SE3 T_sensor_world =
      scene_.sensors.at(std::size_t(sensor)).T_world_sensor.at(frame).inverse();
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

namespace {

// The description of sensor `k`'s dataset.
DatasetInfo dataset_info(const SceneRenderer& renderer, int k) {
  const Scene& scene = renderer.scene();
  const SceneObject& tracked = scene.objects[scene.tracked_object];
  DatasetInfo info;
  info.sensor = renderer.sensor(k).sensor();
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
  info.render_known = true;
  info.shadows = scene.render.shadows;
  if (!scene.render.background.empty()) {
    info.background = fs::absolute(scene.render.background).lexically_normal().string();
  }
  return info;
}

// Frame `frame` of sensor `k`, as its dataset stores it (as frame `index` of `writer`'s).
void write_rendered_frame(const SceneRenderer& renderer, int frame, int k,
                          const RenderedFrame& rendered, DatasetWriter& writer, int index) {
  const Scene& scene = renderer.scene();
  FramePose pose;
  pose.frame = index;
  pose.time_s = frame / scene.fps;
  pose.T_world_object = scene.objects[scene.tracked_object].T_world_object.at(frame);
  pose.T_world_sensor = scene.sensors[k].T_world_sensor.at(frame);
  pose.contact = rendered.stats.contact;
  FrameImages images = rendered.images;
  if (!rendered.contact_points_object.empty()) {
    images.contact_points = rendered.contact_points_object[scene.tracked_object];
  }
  writer.write_frame(pose, images);
}

// Bytes of the frame files a render of `frames` frames into `dir` replaces (an earlier dataset's
// of the same outputs), and of its poses.csv.
std::uintmax_t replaced_bytes(const std::string& dir, const std::vector<std::string>& outputs,
                              int frames) {
  std::error_code ec;
  if (!fs::exists(fs::path(dir) / "dataset.json", ec)) return 0;
  std::uintmax_t bytes = 0;
  const auto add = [&](const fs::path& file) {
    const std::uintmax_t size = fs::file_size(file, ec);
    if (!ec) bytes += size;
  };
  add(fs::path(dir) / "poses.csv");
  for (const std::string& output : outputs) {
    // The files there, not the frames' names: a render may be of millions of frames.
    for (const auto& entry : fs::directory_iterator(fs::path(dir) / output, ec)) {
      const std::string stem = entry.path().stem().string();
      if (stem.empty() || stem.size() > 9 ||
          !std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; })) {
        continue;
      }
      const int frame = std::stoi(stem);
      if (frame < frames &&
          entry.path().filename() == fs::path(dataset_frame_path(dir, output, frame)).filename()) {
        add(entry.path());
      }
    }
  }
  return bytes;
}

// The free space of the disk that will hold `path` (its nearest existing folder's); nullopt when
// the system does not say.
std::optional<std::uintmax_t> free_bytes(fs::path path) {
  std::error_code ec;
  path = fs::absolute(path, ec);
  while (!path.empty() && !fs::exists(path, ec)) {
    if (path == path.parent_path()) break;
    path = path.parent_path();
  }
  const fs::space_info space = fs::space(path, ec);
  if (ec) return std::nullopt;
  return space.available;
}

}  // namespace

int frames_in_flight(std::uintmax_t pixels, int frames, int concurrency,
                     std::optional<std::uintmax_t> available_bytes) {
  const int wanted = std::max(1, std::min(frames, concurrency));
  if (!available_bytes) return wanted;
  const std::uintmax_t frame = std::max<std::uintmax_t>(1, pixels * kFrameBytesPerPixel);
  return int(std::min<std::uintmax_t>(std::uintmax_t(wanted), *available_bytes / frame));
}

std::uintmax_t estimate_dataset_bytes(const SceneRenderer& renderer) {
  static std::atomic<int> calls{0};
  std::error_code ec;
  const fs::path temp = fs::temp_directory_path(ec);
  if (ec) return 0;  // no scratch folder (TMPDIR names none): no estimate
  const fs::path scratch =
      temp / ("pg_render_estimate_" + std::to_string(::getpid()) + "_" + std::to_string(calls++));
  const int frame = renderer.scene().frames / 2;  // more likely in contact than the first
  std::uintmax_t total = 0;
  try {
    const std::vector<RenderedFrame> rendered = renderer.render_frame(frame);
    for (int k = 0; k < renderer.sensor_count(); ++k) {
      const fs::path dir = scratch / std::to_string(k);
      DatasetInfo info = dataset_info(renderer, k);
      const int frames = info.frames;
      info.frames = 1;  // the writer keeps a pose per frame: the one, stored as frame 0
      DatasetWriter writer(dir.string(), info);
      write_rendered_frame(renderer, frame, k, rendered[k], writer, 0);
      if (info.has_output("color"))
        writer.write_background(renderer.sensor(k).background_color_u8());
      std::uintmax_t frame_files = 0;
      for (const std::string& output : info.outputs) {
        std::error_code size_ec;
        const std::uintmax_t size =
            fs::file_size(dataset_frame_path(dir.string(), output, 0), size_ec);
        if (!size_ec) frame_files += size;
      }
      // The rest (dataset.json, background.png) once; a poses.csv row is under 400 bytes.
      total += folder_bytes(dir.string()) + (frame_files + 400) * std::uintmax_t(frames - 1) + 400;
    }
  } catch (const std::exception&) {
    total = 0;  // the scratch folder cannot be written: no estimate
  }
  fs::remove_all(scratch, ec);
  return total;
}

std::string untracked_contact_warning(const RenderSummary& summary, const Scene& scene) {
  const std::string tracked = scene.objects[std::size_t(scene.tracked_object)].name;
  const bool several = summary.sensor_contact.size() > 1;
  std::string text;
  const auto line = [&](const std::string& body) {
    text += (text.empty() ? "" : "\n") + std::string("warning: ") + scene.path + ": " + body;
  };
  for (std::size_t i = 0; i < summary.sensor_contact.size(); ++i) {
    const SensorContact& c = summary.sensor_contact[i];
    std::string others;
    for (const int k : c.others) {
      others += (others.empty() ? "'" : ", '") + scene.objects[std::size_t(k)].name + "'";
    }
    const std::string whose = several ? "sensor '" + scene.sensors[i].name + "': in " : "in ";
    const std::string frames = " of " + std::string(several ? "its " : "the ") +
                               std::to_string(c.contact_frames) + " contact frames ";
    const std::string gel = several ? "its gel" : "the gel";
    const std::string dataset = several ? "its dataset" : "the dataset";
    if (c.untracked_frames > 0) {
      line(whose + std::to_string(c.untracked_frames) + frames +
           "only objects other than the tracked one ('" + tracked + "', tracked_object) touch " +
           gel + " (" + others + "); a tracker reading " + dataset +
           " takes their contact for the tracked object's");
    }
    if (c.shared_frames > 0) {
      line(whose + std::to_string(c.shared_frames) + frames + "another object (" + others +
           ") touches " + gel + " along with the tracked one ('" + tracked +
           "'); a tracker reading " + dataset + " takes both contacts for the tracked object's");
    }
  }
  return text;
}

namespace {

// A scene of several sensors writes OUT/sensors.json and a dataset folder per sensor: OUT must be
// new, empty, or an earlier such render (its index listing dataset folders), never a folder of
// other files, whose own sensors.json or same-named folders the render would replace.
void check_sensors_folder(const std::string& out_dir, int sensors) {
  std::error_code ec;
  const std::string what = "a scene of " + std::to_string(sensors) +
                           " sensors writes one dataset per sensor into their own folders, "
                           "next to their index " +
                           kSensorIndexFile +
                           ", under a new or empty "
                           "folder or an earlier render of several sensors";
  if (!fs::exists(out_dir, ec)) return;
  if (!fs::is_directory(out_dir, ec)) {
    throw InputError(out_dir + ": exists and is not a folder; " + what);
  }
  if (fs::is_empty(out_dir, ec)) return;
  if (fs::exists(fs::path(out_dir) / "dataset.json", ec)) {
    throw InputError(out_dir + ": holds a dataset; " + what);
  }
  bool earlier_render = false;
  try {
    const std::vector<std::string> dirs = sensor_dataset_dirs(out_dir);
    earlier_render = !dirs.empty() && std::all_of(dirs.begin(), dirs.end(), [](const auto& d) {
      return fs::is_regular_file(fs::path(d) / "dataset.json");
    });
  } catch (const InputError&) {
    // an index of another format, or of folders that are not there: not an earlier render
  }
  if (!earlier_render) {
    throw InputError(out_dir + ": is not empty and holds no earlier render of several sensors (" +
                     kSensorIndexFile +
                     " listing their dataset folders), so writing one there could replace your "
                     "files; " +
                     what);
  }
}

}  // namespace

RenderSummary render_scene_to_dataset(const SceneRenderer& renderer, const std::string& out_dir,
                                      const ProgressFn& progress) {
  const Scene& scene = renderer.scene();
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
  if (renderer.sensor_count() > 1) check_sensors_folder(out_dir, renderer.sensor_count());
  for (const auto& dir : dirs) DatasetWriter::check_folder(dir);
  // A folder that cannot be made fails here, named as such (rather than as a disk with no free
  // space: /proc/x). Made for the check, it goes again (with the parents made for it) when the
  // render is refused below.
  std::error_code ec;
  fs::path first_made = fs::absolute(out_dir, ec).lexically_normal();
  if (fs::exists(first_made, ec)) first_made.clear();
  while (!first_made.empty() && first_made.has_parent_path() &&
         first_made.parent_path() != first_made && !fs::exists(first_made.parent_path(), ec)) {
    first_made = first_made.parent_path();
  }
  fs::create_directories(out_dir, ec);
  if (ec || !fs::is_directory(out_dir)) {
    std::error_code link_ec;
    if (fs::is_symlink(out_dir, link_ec) && !fs::exists(out_dir, link_ec)) {  // "File exists"
      throw InputError(out_dir + ": cannot create the output folder: a symbolic link to " +
                       fs::read_symlink(out_dir, link_ec).string() +
                       ", which does not exist (make the folder it points to, or remove it)");
    }
    throw InputError(out_dir + ": cannot create the output folder" +
                     (ec ? ": " + ec.message() : std::string(": not a folder")));
  }
  // Memory: each frame in flight holds its sensors' images. Fewer frames run at once when the
  // machine's available memory holds fewer (an image of 8192 x 8192 px holds 8 GB a frame); a
  // render with room for none is refused before it starts rather than killed when it runs out.
  const std::uintmax_t pixels = sensor_pixels(scene);
  summary.frame_memory_bytes = pixels * kFrameBytesPerPixel;
  const int concurrency = int(std::min<std::size_t>(
      std::size_t(tbb::this_task_arena::max_concurrency()),
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
  const std::optional<std::uintmax_t> memory = available_memory_bytes();
  const int in_flight = frames_in_flight(pixels, scene.frames, concurrency, memory);
  if (in_flight == 0) {
    if (!first_made.empty()) fs::remove_all(first_made, ec);  // only folders made just now
    throw InputError(out_dir + ": a frame of this render needs about " +
                     size_text(summary.frame_memory_bytes) + " of memory (" +
                     std::to_string(pixels) + " px over " +
                     std::to_string(renderer.sensor_count()) + " sensor(s)) and the machine has " +
                     size_text(*memory) + " available; render smaller images (--width, --height)");
  }
  if (in_flight < frames_in_flight(pixels, scene.frames, concurrency, std::nullopt)) {
    summary.frames_in_flight = in_flight;  // fewer than without the memory's bound
  }
  // And the disk's space, before an earlier dataset there is touched: a render that cannot fit
  // would stop half-way with a full disk.
  summary.bytes_estimate = estimate_dataset_bytes(renderer);
  std::uintmax_t replaced = 0;
  for (const auto& dir : dirs) replaced += replaced_bytes(dir, scene.render.outputs, scene.frames);
  const std::optional<std::uintmax_t> available = free_bytes(out_dir);
  if (available && summary.bytes_estimate > *available + replaced) {
    if (!first_made.empty()) fs::remove_all(first_made, ec);  // only folders made just now
    throw InputError(
        out_dir + ": the render needs about " + size_text(summary.bytes_estimate) + " (" +
        std::to_string(scene.frames) + " frames x " + std::to_string(renderer.sensor_count()) +
        " sensor(s)) and the disk holding it has " + size_text(*available + replaced) +
        (replaced > 0 ? " free, with the earlier dataset's frames it would replace" : " free") +
        "; free some space, or render fewer frames, fewer outputs (--outputs) or "
        "smaller images (--width, --height)");
  }
  std::vector<std::unique_ptr<DatasetWriter>> writers;
  for (int i = 0; i < renderer.sensor_count(); ++i) {
    const DatasetInfo info = dataset_info(renderer, i);
    const std::string& dir = dirs[i];
    writers.push_back(std::make_unique<DatasetWriter>(dir, info));
    if (info.has_output("color"))
      writers.back()->write_background(renderer.sensor(i).background_color_u8());
    summary.dataset_dirs.push_back(dir);
  }
  std::atomic<int> done{0}, contact_frames{0}, clamped_frames{0};
  std::mutex progress_mutex, contact_mutex;
  summary.sensor_contact.assign(std::size_t(renderer.sensor_count()), SensorContact{});
  std::vector<std::vector<bool>> others_seen(std::size_t(renderer.sensor_count()),
                                             std::vector<bool>(scene.objects.size(), false));
  // Each frame's files encoded on the thread that rendered it, while the render lasts: the frames
  // already keep every core busy (set_image_codec_threads).
  const ScopedImageCodecThreads codec_threads(1);
  const auto start = std::chrono::steady_clock::now();
  const auto render_one = [&](int frame) {
    const auto frames = renderer.render_frame(frame);
    bool contact = false, clamped = false;
    for (int i = 0; i < renderer.sensor_count(); ++i) {
      const RenderStats& stats = frames[i].stats;
      write_rendered_frame(renderer, frame, i, frames[i], *writers[i], frame);
      contact = contact || stats.contact;
      clamped = clamped || stats.clamped_pixels > 0;
      if (!stats.contact) continue;
      // Per sensor: each dataset is tracked as the tracked object's. Another object in its image
      // (alone, or beside the tracked one, whose cloud it joins) would be taken for it.
      const std::vector<int>& pixels = stats.object_contact_pixels;
      const bool tracked_here = pixels.empty() || pixels[std::size_t(scene.tracked_object)] > 0;
      bool other = false;
      std::lock_guard<std::mutex> lock(contact_mutex);
      for (std::size_t k = 0; k < pixels.size(); ++k) {
        if (int(k) == scene.tracked_object || pixels[k] == 0) continue;
        other = true;
        others_seen[std::size_t(i)][k] = true;
      }
      SensorContact& c = summary.sensor_contact[std::size_t(i)];
      ++c.contact_frames;
      c.untracked_frames += !tracked_here;
      c.shared_frames += tracked_here && other;
    }
    contact_frames += contact;
    clamped_frames += clamped;
    const int n = ++done;
    if (progress) {
      std::lock_guard<std::mutex> lock(progress_mutex);
      progress(n, scene.frames);
    }
  };
  if (summary.frames_in_flight > 0) {  // an arena of that many threads (a frame's own loops too)
    tbb::task_arena arena(summary.frames_in_flight);
    arena.execute([&] { tbb::parallel_for(0, scene.frames, render_one); });
  } else {
    tbb::parallel_for(0, scene.frames, render_one);
  }
  for (auto& w : writers) w->finish();
  if (renderer.sensor_count() > 1) {
    // The earlier render's list, read leniently: it is replaced below, whatever it holds.
    std::ifstream earlier_index(fs::path(out_dir) / kSensorIndexFile);
    const auto earlier = nlohmann::json::parse(earlier_index, nullptr, false);
    if (earlier.is_object() && earlier.contains("sensors") && earlier["sensors"].is_array()) {
      for (const auto& name : earlier["sensors"]) {
        if (!name.is_string()) continue;
        const auto known = std::find_if(scene.sensors.begin(), scene.sensors.end(),
                                        [&](const auto& s) { return s.name == name; });
        const fs::path folder = fs::path(out_dir) / name.get<std::string>();
        if (known == scene.sensors.end() && fs::is_directory(folder, ec)) {
          summary.earlier_sensor_dirs.push_back(folder.string());
        }
      }
    }
    std::vector<std::string> names;
    for (const auto& sensor : scene.sensors) names.push_back(sensor.name);
    write_sensor_index(out_dir, names);
  }
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  summary.contact_frames = contact_frames;
  summary.clamped_frames = clamped_frames;
  for (std::size_t i = 0; i < others_seen.size(); ++i) {
    for (std::size_t k = 0; k < others_seen[i].size(); ++k) {
      if (others_seen[i][k]) summary.sensor_contact[i].others.push_back(int(k));
    }
  }
  return summary;
}

}  // namespace pg
