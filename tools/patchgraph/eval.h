#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "track_args.h"

namespace pg {

struct EvalArgs {
  std::vector<std::string> datasets;  // dataset folders or folders holding datasets
  std::vector<std::string> methods;   // empty: all four
  std::string out;
  TrackArgs track;  // shared tracking options (its method and, with seeds, its seed ignored)
  // --seeds: every dataset and method once per seed (each mixed with the dataset's name, as
  // track.seed is), the summary's medians over all of them; empty: track.seed alone.
  std::vector<std::uint64_t> seeds;
  // Runs tracked at once, each on its own thread (0: one per core). 1 keeps the update times
  // those of a run alone.
  int jobs = 1;
  // Keep the runs an earlier eval left in OUT/runs that were made with the same settings
  // (kept_track_run) and track only the others.
  bool resume = false;
  bool no_plots = false;
};

// Tracks every dataset with every method, writes OUT/results.csv, OUT/summary.md (median and
// quartiles of the final errors per object and method), per-run outputs under OUT/runs/, and
// the plots (OUT/boxplots.png, OUT/trajectories_<object>.png) with tools/plot_eval.py. With
// several seeds, summary.md also gives each seed's medians.
int run_eval(const EvalArgs& args);

}  // namespace pg
