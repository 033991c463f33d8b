#pragma once
#include <string>
#include <vector>

#include "track_args.h"

namespace pg {

struct EvalArgs {
  std::vector<std::string> datasets;  // dataset folders or folders holding datasets
  std::vector<std::string> methods;   // empty: all four
  std::string out;
  TrackArgs track;  // shared tracking options (its method is ignored)
  bool no_plots = false;
};

// Tracks every dataset with every method, writes OUT/results.csv, OUT/summary.md (median and
// quartiles of the final errors per object and method), per-run outputs under OUT/runs/, and
// the plots (OUT/boxplots.png, OUT/trajectories_<object>.png) with tools/plot_eval.py.
int run_eval(const EvalArgs& args);

}  // namespace pg
