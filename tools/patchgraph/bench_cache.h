#pragma once
// `patchgraph bench`'s render cache: each benchmark scene rendered once per resolution and frame
// count into a folder named by what the render depends on, reused by later runs.
#include <string>
#include <vector>

#include "pg/sim/scene.h"

namespace pg {

// A scene read and checked before anything renders: one sensor, its meshes load, its background
// image is there. `key` names its cache entries: a hash of the scene file's text, its sensors'
// models and the bytes of each file it names (meshes, background image), so that another scene of
// the same name, a scene edited since or a mesh replaced renders anew, wherever the scene is
// given from. (A renderer changed since is not seen: docs/benchmarks.md says to clear the cache.)
struct BenchScene {
  std::string path;
  Scene scene;
  std::string key;
};
BenchScene check_bench_scene(const std::string& path);

// The cache entry of `scene` at that resolution and frame count (frames 0: the scene's own).
std::string cache_entry(const BenchScene& scene, int width, int height, int frames,
                        const std::string& cache);

// The entry, rendered with `outputs` unless a complete render is there already. A Ctrl-C while
// rendering says that the entry is unfinished; a folder at the entry that holds no dataset is
// named as the cache's, with what to do.
std::string cached_dataset(const BenchScene& scene, int width, int height, int frames,
                           const std::vector<std::string>& outputs, const std::string& cache);

}  // namespace pg
