#include "track_args.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <utility>

#include "../common/cli_main.h"
#include "pg/core/error.h"
#include "pg/core/hash.h"
#include "pg/learn/normal_model.h"
#include "pg/sim/mesh.h"
#include "pg/sim/mesh_sampling.h"
#include "pg/sim/shading_inversion.h"

namespace pg {

void add_track_options(CLI::App& app, TrackArgs& a, bool with_method) {
  if (with_method) {
    app.add_option("--method,-m", a.method, "constvel, imagetoimage, patchgraph (default), gtpatch")
        ->check(CLI::IsMember(method_names()));
  }
  app.add_option("--normals", a.normals,
                 "Normals source: gt (the dataset's normal images), shading (the colour images "
                 "read through the inverse of the sensor model's shading, no network; exact only "
                 "for renders of that sensor), a model file from train-normals (applied to the "
                 "colour images), or one model per sensor in the sequence's order, separated by "
                 "commas (sensors of different sizes or illumination; so a model's path cannot "
                 "hold a comma)");
  app.add_option("--normals-threads", a.normals_threads,
                 "Torch threads for --normals MODEL (default 1; 0: all cores). The model runs "
                 "beside the tracker's update (unless --no-prefetch), which takes a core of its "
                 "own")
      ->check(kThreads);
  app.add_option("--normals-phases", a.normals_phases,
                 "Average --normals MODEL over the frame shifted by a pixel: 1 (default), 2 or "
                 "4 passes per frame, less error for more time")
      ->check(CLI::IsMember({1, 2, 4}));
  app.add_option("--blend-shading", a.blend_shading,
                 "Average --normals MODEL's normals with the shading's inverse (--normals "
                 "shading), this its weight from 0 (default: the model alone) to 1; for renders "
                 "of the dataset's sensor")
      ->check(range_check(0, 1));
  app.add_option(
      "--config", a.config,
      "Tracker config JSON (depth, mask, icp options): each key given replaces the "
      "default, the built-in options (for --normals MODEL or shading with mask.relative_depth "
      "0.2, icp.symmetric false, icp.flat_radius_m 0.02 and depth.integration averaged)");
  app.add_option("--window", a.window, "Frames in the fixed-lag window; 0 = batch (default 5)")
      ->check(kNonNegative);
  app.add_option("--keyframe-interval", a.keyframe_interval,
                 "Frames between patch key frames (default " +
                     std::to_string(TrackArgs().keyframe_interval) + ")")
      ->check(kPositive);
  app.add_option(
         "--keyframe-settle", a.keyframe_settle,
         "Frames after which a key frame's cloud moves to the pose the fixed-lag window "
         "settled on for it, at most window - 1; 0 keeps the pose it was fused with (default " +
             std::to_string(TrackArgs().keyframe_settle) + ")")
      ->check(kNonNegative);
  app.add_option("--motion-frame", a.motion_frame,
                 "Frame of the motion priors while in contact: sensor (default; the object is "
                 "held and moves with the sensor) or world (the sensor moves over a fixed "
                 "object); the same for a still sensor")
      ->check(CLI::IsMember({"sensor", "world"}));
  app.add_flag("--no-registration-information", a.no_registration_information,
               "Fixed sigmas for registration factors instead of the ICP Hessian's shape");
  // The factor sigmas; help shows GraphOptions' defaults (the paper's values), kept when unset.
  const GraphOptions graph;
  const struct {
    const char* name;
    double* value;
    const char* factor;
    double fallback;
    bool may_be_zero;  // the damping prior's 0 turns it off
  } sigmas[] = {
      {"--registration-sigma", &a.registration_sigma,
       "the image-to-image and image-to-patch factors", graph.sigma_image_to_image, false},
      {"--velocity-sigma", &a.velocity_sigma, "the constant-velocity factor", graph.sigma_velocity,
       false},
      {"--ee-sigma", &a.end_effector_sigma, "the end-effector prior", graph.sigma_end_effector,
       false},
      {"--vision-sigma", &a.vision_sigma, "the vision prior on each episode's first pose",
       graph.sigma_vision, false},
      {"--damping-sigma", &a.damping_sigma, "the zero-velocity (damping) prior; 0 turns it off",
       graph.sigma_damping, true},
  };
  for (const auto& s : sigmas) {
    app.add_option(s.name, *s.value,
                   std::string("Sigma of ") + s.factor + " [m, rad] (default " +
                       format_number(s.fallback) + ")")
        ->check(range_check(kMinFactorSigma, kMaxFactorSigma, s.may_be_zero));
  }
  const std::string gate = format_number(graph.image_to_image_gate_rad);
  app.add_option("--image-to-image-gate", a.image_to_image_gate,
                 std::string("Leave a frame's image-to-image factor out when it and the "
                             "image-to-patch registration turn the object this far apart [rad] "
                             "(default ") +
                     gate + ", off for --normals MODEL or shading; 0 = off)")
      ->check(kNonNegative);
  app.add_option("--ee-noise", a.end_effector_noise,
                 "Sigma of the simulated sensor pose noise [m, rad] (default " +
                     format_number(TrackOptions().end_effector_noise) + "; 0 for a recording)")
      ->check(range_check(0, kMaxPoseNoise));
  app.add_option("--vision-noise", a.vision_noise,
                 "Sigma of the simulated vision prior noise [m, rad] (default " +
                     format_number(TrackOptions().vision_noise) + "; 0 for a recording)")
      ->check(range_check(0, kMaxPoseNoise));
  app.add_option("--seed", a.seed,
                 "Seed of the simulated measurement noise (default 0; eval mixes it with each "
                 "dataset's folder name: results.csv's seed column)")
      ->check(kSeed);
  app.add_flag("--compare-batch", a.compare_batch,
               "Afterwards re-solve the whole sequence at once and report the difference (keeps "
               "every frame's factors in memory, about 2.5 kB a frame)");
  app.add_flag("--no-prefetch", a.no_prefetch,
               "Read each frame's images (and run --normals MODEL) on the tracking thread, not a "
               "frame ahead on a second one: slower, but nothing runs beside the timed update");
  app.add_option("--max-translation", a.max_translation_m,
                 "Accuracy gate [m]: exit 3 when the final translation error (eval: the median "
                 "per object and method) is above it")
      ->check(kPositive);
  app.add_option("--max-rotation", a.max_rotation_rad,
                 "Accuracy gate [rad]: exit 3 when the final rotation error (eval: the median "
                 "per object and method) is above it")
      ->check(kPositive);
}

namespace {

// "x > bound" with six significant digits, or as many more as it takes to tell them apart (an
// error just above its bound printed as "0.169383 mm > 0.169383 mm").
std::string above(double x, double bound, const char* unit) {
  const auto text = [](double v, int digits) {
    char buffer[40];
    std::snprintf(buffer, sizeof buffer, "%.*g", digits, v);
    return std::string(buffer);
  };
  int digits = 6;
  while (digits < 17 && text(x, digits) == text(bound, digits)) ++digits;
  return text(x, digits) + " " + unit + " > " + text(bound, digits) + " " + unit;
}

}  // namespace

bool within_accuracy_gate(const TrackArgs& a, const std::string& what, double translation_m,
                          double rotation_rad) {
  if ((a.max_translation_m >= 0 || a.max_rotation_rad >= 0) &&
      !(std::isfinite(translation_m) && std::isfinite(rotation_rad))) {
    std::fprintf(stderr,
                 "accuracy gate missed: %s has no final error to check (no object pose at the "
                 "last frame)\n",
                 what.c_str());
    return false;
  }
  bool ok = true;
  if (a.max_translation_m >= 0 && !(translation_m <= a.max_translation_m)) {
    std::fprintf(stderr, "accuracy gate missed: %s final translation error %s\n", what.c_str(),
                 above(translation_m * 1e3, a.max_translation_m * 1e3, "mm").c_str());
    ok = false;
  }
  if (a.max_rotation_rad >= 0 && !(rotation_rad <= a.max_rotation_rad)) {
    std::fprintf(stderr, "accuracy gate missed: %s final rotation error %s\n", what.c_str(),
                 above(rotation_rad, a.max_rotation_rad, "rad").c_str());
    ok = false;
  }
  return ok;
}

void check_shading_readable(const Dataset& dataset) {
  const DatasetInfo& info = dataset.info();
  if (info.on_real_background() && !(info.sensor.shading.background_gain > 0)) {
    throw InputError(dataset.dir() + "/dataset.json: sensor.shading.background_gain " +
                     format_number(info.sensor.shading.background_gain) +
                     ": its frames, a real background plus the shading's change scaled by this "
                     "gain, show none of it; the shading's inverse has nothing to read");
  }
}

ImageF blend_normals(ImageF a, const ImageF& b, float w) {
  if (a.data.size() != b.data.size()) throw std::logic_error("blend_normals: sizes differ");
  for (std::size_t i = 0; i + 2 < a.data.size(); i += 3) {
    float v[3], norm_sq = 0;
    for (int c = 0; c < 3; ++c) {
      v[c] = (1 - w) * a.data[i + c] + w * b.data[i + c];
      norm_sq += v[c] * v[c];
    }
    // Two opposite normals average to nothing: a's stands.
    if (!(norm_sq > 1e-12f)) continue;
    const float inv = 1.0f / std::sqrt(norm_sq);
    for (int c = 0; c < 3; ++c) a.data[i + c] = v[c] * inv;
  }
  return a;
}

NormalsModels load_normals_models(const TrackArgs& a) {
  // The first of the options' checks that track, eval and bench make: this one, of two options.
  if (a.window > 0 && a.keyframe_settle > a.window - 1) {
    throw UsageError("--keyframe-settle " + std::to_string(a.keyframe_settle) +
                     ": at most --window - 1 = " + std::to_string(a.window - 1) +
                     " (the window solves a frame for the last time that many frames after it)");
  }
  const bool no_model = a.normals == "gt" || a.normals == kShadingNormals;
  if (a.blend_shading > 0 && no_model) {
    throw UsageError("--blend-shading " + format_number(a.blend_shading) +
                     ": averages a model's normals with the shading's inverse; give --normals "
                     "MODEL (--normals shading is the inverse alone)");
  }
  if (a.normals_phases > 1 && no_model) {
    throw UsageError("--normals-phases " + std::to_string(a.normals_phases) +
                     ": averages a model's passes over shifted frames; --normals " + a.normals +
                     " reads each pixel once (give --normals MODEL, or leave the option out)");
  }
  if (no_model) return {};
  if (a.normals.empty()) throw InputError("--normals: empty; give gt or a model file");
  const std::vector<std::string> paths = comma_items(a.normals);
  const unsigned cores = std::thread::hardware_concurrency();
  static bool noted = false;  // once, though eval loads the models once per job
  if (cores > 0 && a.normals_threads > int(cores) && !std::exchange(noted, true)) {
    std::fprintf(stderr,
                 "note: --normals-threads %d on %u cores: the network's threads share them and "
                 "wait on each other, many times slower than one per core (0: all cores)\n",
                 a.normals_threads, cores);
  }
  std::map<std::string, std::shared_ptr<const NormalEstimator>> loaded;  // a file named twice
  NormalsModels models;
  for (const std::string& path : paths) {
    if (path.empty() || path == "gt" || path == kShadingNormals) {
      throw UsageError("--normals " + a.normals + ": " +
                       (path.empty() ? "an empty model name in the list"
                                     : path + " is for every sensor or none") +
                       "; give gt, shading, one model file for every sensor, or one per sensor "
                       "in the sequence's order, separated by commas");
    }
    auto& model = loaded[path];
    if (!model) {
      auto estimator =
          std::make_shared<NormalEstimator>(NormalEstimator::load(path, a.normals_threads));
      estimator->set_phases(a.normals_phases);
      model = estimator;
    }
    models.push_back(model);
  }
  return models;
}

const NormalEstimator* normals_model_for(const NormalsModels& models, std::size_t sensor) {
  if (models.empty()) return nullptr;
  if (models.size() == 1) return models[0].get();
  if (sensor >= models.size()) {
    throw std::logic_error("normals_model_for: no model for sensor " + std::to_string(sensor) +
                           " (check_normals_models first)");
  }
  return models[sensor].get();
}

void warn_of_other_optics(const NormalEstimator& model, const DatasetInfo& info,
                          const std::string& where) {
  const std::string background = model.background_difference(info);
  if (!background.empty()) {
    std::fprintf(stderr,
                 "warning: %s: %s; train a model on such frames (docs/learned_normals.md "
                 "\"Training data of your own\")\n",
                 where.c_str(), background.c_str());
  }
  const std::string differ = model.sensor_difference(info.sensor);
  if (differ.empty()) return;
  std::fprintf(stderr,
               "warning: %s: its sensor differs in %s from the sensor %s was trained on "
               "(%s): the network reads other shading as other slopes; train a model on this "
               "sensor's images (docs/learned_normals.md \"Training data of your own\")\n",
               where.c_str(), differ.c_str(), model.path().c_str(),
               model.info().sensor.name.c_str());
}

void check_normals_models(const std::string& normals, const NormalsModels& models,
                          const std::vector<const Dataset*>& datasets, bool blend_shading) {
  if (models.size() > 1 && models.size() != datasets.size()) {
    std::string names;
    for (const Dataset* d : datasets) names += (names.empty() ? "" : ", ") + d->dir();
    throw UsageError("--normals: " + std::to_string(models.size()) + " models for " +
                     std::to_string(datasets.size()) + " sensor(s) (" + names +
                     "); give one model for every sensor, or one per sensor in that order");
  }
  for (std::size_t k = 0; k < datasets.size(); ++k) {
    const NormalEstimator* model = normals_model_for(models, k);
    const bool shading = normals == kShadingNormals;
    check_normals_source(*datasets[k], model ? model->path() : shading ? normals : "gt");
    if (shading || blend_shading) check_shading_readable(*datasets[k]);
    const DatasetInfo& info = datasets[k]->info();
    if ((shading || blend_shading) && info.scene.empty() && !info.sensor.lights_measured) {
      std::fprintf(stderr,
                   "warning: %s: no scene rendered it (a recording), and its dataset.json's "
                   "sensor model's lights were not measured: the shading's inverse (--normals "
                   "shading, --blend-shading) reads its change from the no-contact image through "
                   "them, which describe a real sensor's only if measured (patchgraph fit-sensor "
                   "on its ball presses, then recording --sensor-file); a network trained on its "
                   "presses reads it too (docs/learned_normals.md \"Inverting the shading\")\n",
                   datasets[k]->dir().c_str());
    }
    if (model) {
      model->check_sensor(datasets[k]->info().sensor, datasets[k]->dir());
      warn_of_other_optics(*model, datasets[k]->info(), datasets[k]->dir());
    }
  }
}

std::vector<Dataset> open_sequence(const std::string& dir) {
  std::vector<std::string> dirs = sensor_dataset_dirs(dir);
  if (dirs.empty()) dirs = {dir};  // Dataset::open says what it lacks
  std::vector<Dataset> datasets;
  for (const std::string& d : dirs) datasets.push_back(Dataset::open(d));
  if (datasets.size() > 1) {
    try {
      check_given_once(dirs);  // two names of sensors.json may link to one folder
    } catch (const InputError& e) {
      throw InputError(std::string(e.what()) + " in " +
                       (std::filesystem::path(dir) / kSensorIndexFile).string());
    }
    check_same_sequence(dataset_pointers(datasets));
  }
  return datasets;
}

std::vector<const Dataset*> dataset_pointers(const std::vector<Dataset>& datasets) {
  std::vector<const Dataset*> out;
  for (const Dataset& d : datasets) out.push_back(&d);
  return out;
}

void note_long_batch(const TrackArgs& args, const Dataset& dataset) {
  if (args.window != 0 || dataset.frames() <= kLongBatchFrames) return;
  std::fprintf(stderr,
               "note: --window 0 solves all the frames so far at every frame: %s's %d frames will "
               "take about %.0f times as long as its first 300 (at 300 frames a frame takes some "
               "20 ms); --compare-batch solves the whole sequence once, after the fixed-lag "
               "run\n",
               dataset.dir().c_str(), dataset.frames(), std::pow(dataset.frames() / 300.0, 2));
}

int note_missing_frames(const std::vector<const Dataset*>& datasets) {
  const std::vector<std::vector<int>> frames = sequence_frames(datasets);
  int total = 0;
  for (std::size_t k = 1; k < frames.size(); ++k) {
    const int missing = int(std::count(frames[k].begin(), frames[k].end(), -1));
    if (missing == 0) continue;
    total += missing;
    const int first = int(std::find(frames[k].begin(), frames[k].end(), -1) - frames[k].begin());
    std::fprintf(
        stderr,
        "note: %s has no frame within half a frame of %d of the %d frames of %s (the first: its "
        "frame %d); it adds nothing to those (errors.csv: invalid_input)\n",
        datasets[k]->dir().c_str(), missing, datasets[0]->frames(), datasets[0]->dir().c_str(),
        first);
  }
  return total;
}

std::shared_ptr<const PointCloudTree> object_model(const Dataset& dataset) {
  const SurfaceSamples s = sample_surface(load_object_mesh(dataset), kModelSpacingM);
  PointCloud cloud;
  cloud.points = s.points;
  cloud.normals = s.normals;
  return std::make_shared<const PointCloudTree>(std::move(cloud));
}

std::string object_model_key(const Dataset& dataset) {
  const auto& info = dataset.info();
  std::ostringstream key;
  key.precision(17);
  const std::filesystem::path mesh = std::filesystem::path(dataset.dir()) / info.object_mesh;
  std::error_code ec;
  const std::filesystem::path canonical = std::filesystem::weakly_canonical(mesh, ec);
  key << (ec ? mesh.lexically_normal() : canonical).string() << "\n" << info.object_scale;
  return key.str();
}

TrackOptions make_track_options(const TrackArgs& a, const std::vector<const Dataset*>& datasets,
                                const NormalsModels& models,
                                std::shared_ptr<const PointCloudTree> object) {
  if (datasets.empty()) throw std::logic_error("make_track_options: no dataset");
  const Dataset& dataset = *datasets[0];
  TrackOptions o;
  if (a.blend_shading > 0 && models.empty()) {
    throw std::logic_error("make_track_options: --blend-shading without a model");
  }
  // Each sensor's own lights; its change from a real background read where it has one (a
  // blended render, a recording).
  std::shared_ptr<std::vector<ShadingInversion>> inversions;
  if (a.normals == kShadingNormals || a.blend_shading > 0) {
    inversions = std::make_shared<std::vector<ShadingInversion>>();
    for (const Dataset* d : datasets) {
      inversions->emplace_back(d->info().sensor, d->info().on_real_background());
    }
  }
  if (a.normals == kShadingNormals) {
    o.normals = [inversions](std::size_t sensor, const ImageU8& color, const ImageU8& reference) {
      return inversions->at(sensor).normals(color, reference);
    };
    o.normals_name = a.normals;
  } else if (a.normals != "gt") {
    if (models.empty()) throw std::logic_error("make_track_options: --normals not loaded");
    o.normals = [models](std::size_t sensor, const ImageU8& color, const ImageU8& reference) {
      return normals_model_for(models, sensor)->predict(color, reference);
    };
    o.normals_name = a.normals;
    for (const auto& model : models) {
      o.normals_digest += (o.normals_digest.empty() ? "" : ",") + model->info().file_digest;
    }
    // Phase averaging changes the normals: the summary (and eval --resume) tell the runs apart.
    if (a.normals_phases > 1) o.normals_name += "+phases:" + std::to_string(a.normals_phases);
    if (a.blend_shading > 0) {
      o.normals = [models, inversions, w = float(a.blend_shading)](
                      std::size_t sensor, const ImageU8& color, const ImageU8& reference) {
        return blend_normals(normals_model_for(models, sensor)->predict(color, reference),
                             inversions->at(sensor).normals(color, reference), w);
      };
      o.normals_name += "+shading:" + format_number(a.blend_shading);
    }
  }
  o.graph.method = method_from_string(a.method);
  o.graph.window = a.window;
  o.graph.patch.keyframe_interval = a.keyframe_interval;
  // The tracker moves a key frame at most window - 1 frames later (the window's last solve of
  // it): summary.json records what runs, not a larger value asked for.
  o.graph.patch.keyframe_settle_frames = a.keyframe_settle;  // within the window (above)
  o.graph.motion_frame = motion_frame_from_string(a.motion_frame);
  o.graph.registration_information = !a.no_registration_information;
  if (a.registration_sigma > 0) {
    o.graph.sigma_image_to_image = o.graph.sigma_image_to_patch = a.registration_sigma;
  }
  if (a.velocity_sigma > 0) o.graph.sigma_velocity = a.velocity_sigma;
  if (a.end_effector_sigma > 0) o.graph.sigma_end_effector = a.end_effector_sigma;
  if (a.vision_sigma > 0) o.graph.sigma_vision = a.vision_sigma;
  if (a.damping_sigma >= 0) o.graph.sigma_damping = a.damping_sigma;
  // Normals estimated from the colour images (a network's, the shading's inverse) have their own
  // front-end settings and no image-to-image gate (track_dataset.h).
  if (o.normals) use_estimated_normals(o);
  if (a.image_to_image_gate >= 0) o.graph.image_to_image_gate_rad = a.image_to_image_gate;
  // A config file sets the keys it names on top of these (a file naming another key keeps the
  // learned normals' settings).
  if (!a.config.empty()) o.front_end = load_tracker_config(a.config, o.front_end);
  // The noise simulates what a robot's measurements would add to a render's exact poses; a
  // recording's are measured (and its first pose is the sensor's frame, no vision system's).
  const bool recording = dataset.info().scene.empty();
  if (a.end_effector_noise >= 0) {
    o.end_effector_noise = a.end_effector_noise;
  } else if (recording) {
    o.end_effector_noise = 0;
  }
  if (a.vision_noise >= 0) {
    o.vision_noise = a.vision_noise;
  } else if (recording) {
    o.vision_noise = 0;
  }
  o.seed = a.seed;
  o.compare_batch = a.compare_batch;
  // Each frame's estimate goes into the run's results as it is made: the tracker keeps only what
  // its update reads (the same estimates), unless the batch re-solve needs every frame.
  if (o.graph.window > 0 && !o.compare_batch) o.graph.history_frames = o.graph.window + 2;
  o.prefetch = !a.no_prefetch;
  if (o.graph.method == Method::kGroundTruthPatch) {
    o.model_object = object ? std::move(object) : object_model(dataset);
  }
  return o;
}

TriangleMesh load_object_mesh(const Dataset& dataset) {
  const auto& info = dataset.info();
  if (info.object_mesh.empty()) {
    throw InputError(dataset.dir() + "/dataset.json: object.mesh is empty; gtpatch needs the mesh");
  }
  // A relative path is the dataset folder's (as a scene's paths are its file's).
  const std::filesystem::path mesh =
      std::filesystem::path(dataset.dir()) / std::filesystem::path(info.object_mesh);
  TriangleMesh loaded;
  try {
    loaded = load_mesh(mesh.lexically_normal().string(), info.object_scale);
  } catch (const InputError& e) {
    throw InputError(dataset.dir() + "/dataset.json: object.mesh: " + e.what());
  }
  // GroundtruthPatch's model covers the whole surface at the registration's resolution: a
  // metre-sized object would take gigabytes before its first frame.
  const double samples = surface_sample_count(loaded, kModelSpacingM);
  if (samples > kMaxModelPoints) {
    std::ostringstream what;
    what << dataset.dir() << "/dataset.json: object.mesh: " << info.object_mesh << " (scale "
         << info.object_scale << ") is too large for gtpatch's object model: its surface at "
         << kModelSpacingM * 1e3 << " mm spacing is " << std::setprecision(3) << samples / 1e6
         << " M points, at most " << kMaxModelPoints / 1e6
         << " M are kept (about a 0.1 m^2 surface: a 10 cm box); the other methods need no model";
    throw InputError(what.str());
  }
  return loaded;
}

std::uint64_t sequence_seed(std::uint64_t base, const std::string& name) {
  std::uint64_t z = fnv1a(name) ^ (base + 0x9e3779b97f4a7c15ull);  // then SplitMix64's finaliser
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
  return z ^ (z >> 31);
}

}  // namespace pg
