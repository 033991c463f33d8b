#pragma once
// `patchgraph bench`: run time against error over the knobs that trade one for the other.
#include <string>
#include <vector>

namespace pg {

struct TrackBenchArgs {
  std::string out = "bench_out";
  // Benchmark scenes (default: sequences 00-02 of each object, scenes/benchmark/).
  std::vector<std::string> scenes;
  std::string cache;  // rendered datasets, reused between runs (default: OUT/cache)
  // Normals sources: each one besides "gt" adds a row at the settings `patchgraph track --normals
  // SOURCE` gives it, tracked through the same code path.
  std::vector<std::string> normals = {"gt"};
  int frames = 0;      // frames per scene, at least 10 (0: the scene's own, 300)
  int threads = 0;     // oneTBB threads (0: all cores)
  bool quick = false;  // 2 scenes x 60 frames, 6 settings: a smoke test
  bool no_plot = false;
  bool quiet = false;
};

// Renders the scenes (once, into the cache), tracks each with every setting, and writes
// OUT/bench.csv (one row per setting), OUT/bench.md (the table), OUT/runs.csv (every run) and
// OUT/bench.png (time vs error with the Pareto front, tools/plot_bench.py). Prints the table.
int run_track_bench(const TrackBenchArgs& args);

}  // namespace pg
