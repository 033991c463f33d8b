#pragma once
// patchgraph train-normals and eval-normals: the learned-normals network (pg/learn).
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "pg/learn/normal_model.h"

namespace pg {

struct TrainNormalsArgs {
  TrainOptions options;
  std::string labels = "sensor";  // --labels: sensor or gel (TrainOptions::gel_relative)
  bool quiet = false;
};

struct EvalNormalsArgs {
  std::string model;
  std::vector<std::string> data;
  std::string json;  // output file
  int threads = 1;
  int phases = 1;  // NormalEstimator::set_phases
  double blend_shading = 0;  // as track's --blend-shading
  bool quiet = false;
};

struct ModelInfoArgs {
  std::string model;
};

CLI::App* add_train_normals_command(CLI::App& app, TrainNormalsArgs& args);
CLI::App* add_model_info_command(CLI::App& app, ModelInfoArgs& args);
int run_model_info(const ModelInfoArgs& args);
CLI::App* add_eval_normals_command(CLI::App& app, EvalNormalsArgs& args);
int run_train_normals(const TrainNormalsArgs& args);
int run_eval_normals(const EvalNormalsArgs& args);

}  // namespace pg
