#pragma once
#include <string>

namespace pg {

struct BenchArgs {
  int frames = 2000;
  int repeats = 5;
  int threads = 0;
  bool quick = false;
  bool ablation = false;  // each skip switched off in turn, instead of the speed table
  std::string markdown;
};

// Renderer speed: the cases of the renderer issue at 120x160 and 240x320, with and without
// shadows; prints a table of median frames/s.
int run_bench(const BenchArgs& args);

}  // namespace pg
