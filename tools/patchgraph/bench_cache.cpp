#include "bench_cache.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "../common/stop.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/sim/scene_renderer.h"
#include "track_args.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

BenchScene check_bench_scene(const std::string& path) {
  BenchScene s{path, load_scene(path), ""};
  if (s.scene.sensors.size() > 1) {
    throw InputError(path + ": sensors: " + std::to_string(s.scene.sensors.size()) +
                     " sensors; bench times one sensor's tracking (render the scene with tacsim "
                     "and run patchgraph track or eval on it for the sensors together)");
  }
  // What a render would refuse (a mesh that does not load, a missing background), refused now.
  const SceneRenderer renders(s.scene);
  std::string key = file_bytes(path) + "\n";
  for (const SceneSensor& sensor : s.scene.sensors) {
    key += sensor_to_json(sensor.model).dump() + "\n";
  }
  for (const SceneObject& object : s.scene.objects) key += file_bytes(object.mesh_path) + "\n";
  const std::string& background = s.scene.render.background;
  if (!background.empty() && !names_synthetic_background(background)) {
    key += file_bytes(background);
  }
  char hash[20];
  std::snprintf(hash, sizeof hash, "%08llx", (unsigned long long)(sequence_seed(0, key) >> 32));
  s.key = hash;
  return s;
}

std::string cache_entry(const BenchScene& scene, int width, int height, int frames,
                        const std::string& cache) {
  const std::string name = fs::path(scene.path).stem().string() + "_" + scene.key + "_" +
                           std::to_string(width) + "x" + std::to_string(height) + "_" +
                           (frames > 0 ? std::to_string(frames) : std::string("all"));
  return (fs::path(cache) / name).string();
}

std::string cached_dataset(const BenchScene& scene, int width, int height, int frames,
                           const std::vector<std::string>& outputs, const std::string& cache) {
  const std::string dir = cache_entry(scene, width, height, frames, cache);
  if (fs::is_regular_file(fs::path(dir) / "poses.csv")) {
    try {
      const Dataset d = Dataset::open(dir);
      bool complete = true;
      for (const auto& o : outputs) complete = complete && d.info().has_output(o);
      if (complete) return dir;
    } catch (const InputError&) {
      // Incomplete or stale: render again.
    }
  }
  // Rendered again into the folder of an unfinished or incomplete render; a folder of anything
  // else is refused, not deleted.
  try {
    DatasetWriter::check_folder(dir);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + " (an entry of the bench's cache: remove " + dir +
                     " to render it again)");
  }
  Scene s = scene.scene;
  if (frames > 0) s.frames = std::min(s.frames, frames);
  RenderOverrides overrides;
  overrides.outputs = outputs;
  overrides.width = width;
  overrides.height = height;
  try {
    const SceneRenderer renderer(std::move(s), overrides);
    const RenderSummary summary =
        render_scene_to_dataset(renderer, dir, [](int, int) { stop_if_asked(); });
    // As tacsim render says it (once: a cached render is not rendered again).
    const std::string untracked = untracked_contact_warning(summary, renderer.scene());
    if (!untracked.empty()) std::fprintf(stderr, "%s\n", untracked.c_str());
  } catch (const Stopped& e) {
    throw e.with_note("the cache entry " + dir +
                      " is unfinished (the next bench renders it again)");
  }
  return dir;
}

}  // namespace pg
