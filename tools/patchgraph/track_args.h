#pragma once
// Options shared by `patchgraph track` and `patchgraph eval`.
#include <CLI/CLI.hpp>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "pg/graph/track_dataset.h"
#include "pg/learn/normal_model.h"
#include "pg/sim/mesh.h"

namespace pg {

struct TrackArgs {
  // `track`'s datasets: one, or several sensors' of one sequence (the first is the primary).
  std::vector<std::string> datasets;
  std::string out;
  std::string method = "patchgraph";
  // "gt", "shading" (kShadingNormals), a model file from train-normals for every sensor, or one
  // per sensor in the sequence's order, comma-separated (load_normals_models).
  std::string normals = "gt";
  int normals_threads = 1;
  int normals_phases = 1;  // NormalEstimator::set_phases
  // With --normals MODEL: the weight in [0, 1] of the shading's inverse averaged with the model's
  // normals (0: the model alone).
  double blend_shading = 0;
  std::string config;      // tracker config JSON (depth, mask, icp options)
  int window = 5;
  int keyframe_interval = 10;
  int keyframe_settle = PatchMapOptions().keyframe_settle_frames;
  std::string motion_frame = "sensor";  // GraphOptions::motion_frame
  bool no_registration_information = false;
  // Factor sigmas; 0 keeps GraphOptions' own (the paper's values).
  double registration_sigma = 0, velocity_sigma = 0, end_effector_sigma = 0, vision_sigma = 0;
  double damping_sigma = -1;  // < 0 keeps GraphOptions' own; 0 turns the damping prior off
  // [rad]; < 0 keeps GraphOptions' own (off for --normals MODEL); 0 turns it off
  double image_to_image_gate = -1;
  // Simulated pose noise [m, rad]; < 0: TrackOptions' own (1e-5, 1e-4), or 0 for a recording,
  // whose sensor poses are measurements already and whose first pose no vision system gave.
  double end_effector_noise = -1, vision_noise = -1;
  std::uint64_t seed = 0;
  bool quiet = false;
  bool compare_batch = false;
  bool no_prefetch = false;  // TrackOptions::prefetch off
  // Accuracy gate for CI (< 0: off): `track` fails when its final error, `eval` when any object
  // and method's median final error, is above these.
  double max_translation_m = -1, max_rotation_rad = -1;
};

// --normals shading: each sensor's own shading model inverted pixel by pixel (pg/sim/
// shading_inversion.h), no network.
inline const std::string kShadingNormals = "shading";

void add_track_options(CLI::App& app, TrackArgs& args, bool with_method = true);
// The --normals models: none for "gt", one for every sensor, or one per sensor in the order of
// the sequence's datasets ("below.pt,side.pt"; a file named twice is loaded once).
using NormalsModels = std::vector<std::shared_ptr<const NormalEstimator>>;
// Throws InputError naming DIR/dataset.json unless the shading's inverse can read the dataset's
// frames: blended onto a real background, they need a background_gain above 0.
void check_shading_readable(const Dataset& dataset);
// The unit normals of (1 - w) a + w b per pixel (a's where the two cancel): a model's normals
// averaged with the shading's inverse (--blend-shading).
ImageF blend_normals(ImageF a, const ImageF& b, float w);
// --normals of `args` loaded, with its threads and phases (none for gt and shading). Throws
// InputError for an empty name in the list, "gt" or "shading" beside a model, --blend-shading
// without a model, or a file that does not load (naming it); UsageError for --keyframe-settle
// beyond the window.
NormalsModels load_normals_models(const TrackArgs& args);
// The model that reads sensor `sensor`'s images: the one model, or that sensor's; null for none.
const NormalEstimator* normals_model_for(const NormalsModels& models, std::size_t sensor);
// Checks that `models` (--normals `normals`, loaded) fit `datasets` (one sequence's sensors, in
// order): none, one, or one per dataset, and that each dataset has what its source reads (colour
// images of the model's size; for shading its colour images; for gt its normal images). Throws
// InputError naming the dataset, or --normals. For shading (or a model's normals blended with it,
// --blend-shading), warns of a dataset that no scene rendered (a recording: its sensor file
// describes its lights only if they were measured).
void check_normals_models(const std::string& normals, const NormalsModels& models,
                          const std::vector<const Dataset*>& datasets, bool blend_shading = false);
// Warns (stderr) when a dataset's frames (`info`) have another background than `model` was
// trained on (NormalEstimator::background_difference), or its sensor other optics
// (NormalEstimator::sensor_difference); `where` names the dataset.
void warn_of_other_optics(const NormalEstimator& model, const DatasetInfo& info,
                          const std::string& where);
// The datasets of one sequence: DIR's own, or a render of several sensors' (its sensors.json, in
// that order), each opened, and checked to be one sequence (check_same_sequence), all before any
// work. Throws InputError naming what is missing or malformed.
std::vector<Dataset> open_sequence(const std::string& dir);
std::vector<const Dataset*> dataset_pointers(const std::vector<Dataset>& datasets);
// Cameras of their own may start, stop or drop frames apart: prints a note for each sensor of
// `datasets` without a frame at some of the primary's times (sequence_frames), where it adds
// nothing. Returns how many such sensor-frames there are.
int note_missing_frames(const std::vector<const Dataset*>& datasets);
// --window 0 solves all the frames so far at every frame: a frame costs more the longer the
// sequence and the run grows with the square of its frames, which a progress line's estimate
// does not foresee. Prints a note when `dataset` has more than kLongBatchFrames frames.
inline constexpr int kLongBatchFrames = 1000;
void note_long_batch(const TrackArgs& args, const Dataset& dataset);
// Checks --method, loads --config and, for gtpatch, the primary dataset's object mesh. `models`:
// --normals loaded (eval's runs share them; check_normals_models has held for the sequence
// `datasets`, the primary first; --normals shading inverts each one's own sensor).
// `object`: gtpatch's object model when the caller has built it (object_model), else built here.
TrackOptions make_track_options(const TrackArgs& args, const std::vector<const Dataset*>& datasets,
                                const NormalsModels& models,
                                std::shared_ptr<const PointCloudTree> object = nullptr);
// GroundtruthPatch's object model: the mesh's surface sampled every kModelSpacingM, at most
// kMaxModelPoints points (about 0.1 m^2 of surface; points, normals and k-d tree some 350 MB).
inline constexpr double kModelSpacingM = 1e-4;
inline constexpr double kMaxModelPoints = 1e7;
// The dataset's object mesh (dataset.json's object.mesh, relative to its folder), as gtpatch
// registers against it; InputError naming dataset.json's field when it is missing, bad, or too
// large to sample as the model.
TriangleMesh load_object_mesh(const Dataset& dataset);
// gtpatch's object model of `dataset`: its mesh (load_object_mesh) sampled every kModelSpacingM,
// built as the tree it registers against (286 k points for the benchmark's toy human). eval builds
// it once for the runs of every sequence of one object (object_model_key), and --resume, which
// compares settings alone, none.
std::shared_ptr<const PointCloudTree> object_model(const Dataset& dataset);
// What makes `dataset`'s object model: its mesh file (the canonical path) and scale. Sequences of
// one object share it.
std::string object_model_key(const Dataset& dataset);

// Checks one final (or median final) error against the accuracy gate of `args`; prints a line
// to stderr naming `what` and the bound for each bound it misses. True when within the gate.
bool within_accuracy_gate(const TrackArgs& args, const std::string& what, double translation_m,
                          double rotation_rad);

// The noise seed of one sequence of a batch (`eval`, `bench`): the base seed mixed with the
// sequence's name (its dataset folder's name, or its scene file's stem), so each sequence draws
// its own sensor-pose and vision-prior noise, whatever else runs with it, and one run is reproduced
// alone by `patchgraph track DIR --seed S` with S from results.csv or summary.json.
std::uint64_t sequence_seed(std::uint64_t base, const std::string& name);

}  // namespace pg
