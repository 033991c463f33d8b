#pragma once
// Options shared by `patchgraph track` and `patchgraph eval`.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "pg/graph/track_dataset.h"
#include "pg/learn/normal_model.h"

namespace pg {

struct TrackArgs {
  // `track`'s datasets: one, or several sensors' of one sequence (the first is the primary).
  std::vector<std::string> datasets;
  std::string out;
  std::string method = "patchgraph";
  std::string normals = "gt";  // or a model file from train-normals
  int normals_threads = 1;
  int normals_phases = 1;  // NormalEstimator::set_phases
  std::string config;  // tracker config JSON (depth, mask, icp options)
  int window = 5;
  int keyframe_interval = 10;
  std::string motion_frame = "sensor";  // GraphOptions::motion_frame
  bool no_registration_information = false;
  // Factor sigmas; 0 keeps GraphOptions' own (the paper's values).
  double registration_sigma = 0, velocity_sigma = 0, end_effector_sigma = 0, vision_sigma = 0;
  double damping_sigma = -1;  // < 0 keeps GraphOptions' own; 0 turns the damping prior off
  // [rad]; < 0 keeps GraphOptions' own (off for --normals MODEL); 0 turns it off
  double image_to_image_gate = -1;
  double end_effector_noise = 1e-5, vision_noise = 1e-4;
  std::uint64_t seed = 0;
  bool quiet = false;
  bool compare_batch = false;
  // Accuracy gate for CI (< 0: off): `track` fails when its final error, `eval` when any object
  // and method's median final error, is above these.
  double max_translation_m = -1, max_rotation_rad = -1;
};

void add_track_options(CLI::App& app, TrackArgs& args, bool with_method = true);
// The --normals MODEL of `args` loaded, with its threads and phases; null for "gt".
std::shared_ptr<const NormalEstimator> load_normals_model(const TrackArgs& args);
// Checks that `dataset` has what `model` reads (colour images of the model's size), or for null
// (ground-truth normals) its normal images. Throws InputError naming the dataset.
void check_normals_input(const NormalEstimator* model, const Dataset& dataset);
// The datasets of one sequence: DIR's own, or a render of several sensors' (its sensors.json, in
// that order), each opened and checked against `model` (null: ground-truth normals), and
// checked to be one sequence (check_same_sequence), all before any work. Throws InputError
// naming what is missing or malformed.
std::vector<Dataset> open_sequence(const std::string& dir, const NormalEstimator* model);
std::vector<const Dataset*> dataset_pointers(const std::vector<Dataset>& datasets);
// Checks --normals and --method, loads --config and, for gtpatch, the dataset's object mesh.
// `model`: --normals MODEL already loaded (eval's runs share one); null loads it.
TrackOptions make_track_options(const TrackArgs& args, const Dataset& dataset,
                                std::shared_ptr<const NormalEstimator> model = nullptr);

// Checks one final (or median final) error against the accuracy gate of `args`; prints a line
// to stderr naming `what` and the bound for each bound it misses. True when within the gate.
bool within_accuracy_gate(const TrackArgs& args, const std::string& what, double translation_m,
                          double rotation_rad);

// The noise seed of one sequence of a batch (`eval`, `bench`): the base seed mixed with the
// sequence's name (its dataset folder, with its parent's where two share a name, or its scene
// file's stem), so each sequence draws its own sensor-pose and vision-prior noise, whatever else
// runs with it, and one run is reproduced alone by `patchgraph track DIR --seed S` with S from
// results.csv or summary.json.
std::uint64_t sequence_seed(std::uint64_t base, const std::string& name);

}  // namespace pg
