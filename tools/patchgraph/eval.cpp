#include "eval.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <system_error>
#include <thread>

#include "../common/cli_main.h"
#include "../common/plot_script.h"
#include "../common/progress.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/graph/track_dataset.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

// The sequences to run: each root that is one (a dataset, or a render of several sensors with
// its sensors.json), else the sequences one level down in it, in name order.
std::vector<std::string> expand_datasets(const std::vector<std::string>& roots) {
  std::vector<std::string> out;
  for (const auto& root : roots) {
    if (!sensor_dataset_dirs(root).empty()) {
      out.push_back(root);
      continue;
    }
    if (!fs::is_directory(root)) throw InputError(root + ": not a dataset or a folder of datasets");
    std::vector<std::string> found, skipped;  // skipped: folders that hold no dataset
    for (const auto& entry : fs::directory_iterator(root)) {
      if (!sensor_dataset_dirs(entry.path().string()).empty()) {
        found.push_back(entry.path().string());
      } else if (entry.is_directory()) {
        skipped.push_back(entry.path().filename().string());
      }
    }
    if (found.empty()) throw InputError(root + ": holds no dataset (no */dataset.json)");
    if (!skipped.empty()) {  // said, so that a dataset missing its dataset.json is not lost unseen
      std::sort(skipped.begin(), skipped.end());
      std::fprintf(stderr, "note: %s: %zu folder(s) without a dataset.json left out (%s%s)\n",
                   root.c_str(), skipped.size(), skipped.front().c_str(),
                   skipped.size() > 1 ? ", ..." : "");
    }
    std::sort(found.begin(), found.end());
    out.insert(out.end(), found.begin(), found.end());
  }
  return out;
}

// A dataset's folder as given, made absolute and without "." or ".." (a symbolic link to a
// dataset keeps its own name, not its target's: the runs are named as the user named them).
fs::path as_given(const std::string& dir) {
  fs::path p = fs::absolute(dir).lexically_normal();
  return p.has_filename() ? p : p.parent_path();  // "x/" names x
}

// The folder under OUT/runs of each dataset's runs (before "_METHOD"): its own folder's name, or,
// where two datasets share that name, with their parents' names before it (a/x and b/x become
// a_x and b_x). A dataset given twice (also through a folder of datasets, or a link) is an error.
std::vector<std::string> run_names(const std::vector<std::string>& datasets) {
  check_given_once(datasets);
  std::vector<fs::path> given;
  for (const std::string& dir : datasets) given.push_back(as_given(dir));
  std::map<std::string, int> uses;
  for (const fs::path& path : given) ++uses[path.filename().string()];
  std::vector<std::string> names;
  for (std::size_t k = 0; k < datasets.size(); ++k) {
    const std::string& dir = datasets[k];
    std::string name = given[k].filename().string();
    if (uses[name] > 1) name = given[k].parent_path().filename().string() + "_" + name;
    if (std::find(names.begin(), names.end(), name) != names.end()) {
      throw InputError(dir + ": its runs would share OUT/runs/" + name +
                       "_* with another dataset's; rename one of the two folders");
    }
    names.push_back(name);
  }
  return names;
}

// Quartiles by linear interpolation between order statistics.
double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  const double pos = q * (v.size() - 1);
  const std::size_t lo = std::size_t(pos);
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - lo) * (v[hi] - v[lo]);
}

struct Row {
  std::string dataset, object, method, run;
  std::uint64_t eval_seed;  // the --seed (or --seeds value) that s.seed was mixed from
  TrackSummary s;
  std::vector<std::string> warnings;  // track_warnings(s), or as an earlier eval wrote them
};

void write_results_csv(const std::string& path, const std::vector<Row>& rows) {
  std::ostringstream out;
  out.precision(9);
  out << "dataset,object,method,frames,contact_frames,final_translation_error_m,"
         "final_rotation_error_rad,translation_rmse_m,rotation_rmse_rad,median_frame_ms,hz,"
         "lost_frames,degenerate_frames,seed,run,eval_seed,warnings\n";
  for (const auto& r : rows) {
    out << csv_field(r.dataset) << "," << csv_field(r.object) << "," << r.method << ","
        << r.s.frames << "," << r.s.contact_frames << "," << r.s.final_translation_error_m << ","
        << r.s.final_rotation_error_rad << "," << r.s.translation_rmse_m << ","
        << r.s.rotation_rmse_rad << "," << r.s.median_frame_ms << "," << r.s.hz << ","
        << r.s.lost_frames << "," << r.s.degenerate_frames << "," << r.s.seed << ","
        << csv_field(r.run) << "," << r.eval_seed << ",";
    for (std::size_t k = 0; k < r.warnings.size(); ++k) out << (k ? ";" : "") << r.warnings[k];
    out << "\n";
  }
  write_text_atomically(path, out.str());
}

// One object and method's runs: final errors [m, rad], per-frame update times [ms] and the
// runs' eval seeds.
struct Group {
  std::string object, method;
  std::vector<double> translation, rotation, ms;
  std::vector<std::uint64_t> seeds;

  void add(double translation_m, double rotation_rad, double frame_ms, std::uint64_t seed) {
    translation.push_back(translation_m);
    rotation.push_back(rotation_rad);
    ms.push_back(frame_ms);
    seeds.push_back(seed);
  }
  // The runs of one eval seed alone.
  Group of_seed(std::uint64_t seed) const {
    Group g{object, method, {}, {}, {}, {}};
    for (std::size_t i = 0; i < seeds.size(); ++i) {
      if (seeds[i] == seed) g.add(translation[i], rotation[i], ms[i], seed);
    }
    return g;
  }
};

// Groups by object (sorted), then method (in `methods`' order).
std::vector<Group> group_runs(const std::vector<Row>& rows,
                              const std::vector<std::string>& methods) {
  std::map<std::string, std::map<std::string, std::vector<const Row*>>> by;
  for (const auto& r : rows) by[r.object][r.method].push_back(&r);
  std::vector<Group> groups;
  for (const auto& [object, per_method] : by) {
    for (const auto& m : methods) {
      const auto it = per_method.find(m);
      if (it == per_method.end()) continue;
      Group g{object, m, {}, {}, {}, {}};
      for (const Row* r : it->second) {
        g.add(r->s.final_translation_error_m, r->s.final_rotation_error_rad, r->s.median_frame_ms,
              r->eval_seed);
      }
      groups.push_back(std::move(g));
    }
  }
  return groups;
}

// "1.42x" (three significant digits up to 1000x), or "-" where GroundtruthPatch's median is zero
// (nothing to divide by).
std::string ratio_cell(double value, double reference) {
  if (!(reference > 0)) return "-";
  const double ratio = value / reference;
  char cell[32];
  std::snprintf(cell, sizeof(cell), "%.*fx", ratio < 10 ? 2 : ratio < 100 ? 1 : 0, ratio);
  return cell;
}

// Each method's median final errors over GroundtruthPatch's on the same object (the paper's
// "best a method can do", issue 5's 1.5x target); empty without gtpatch among the methods. With
// several eval seeds, also the ratio of each seed's medians, in `seeds`' order.
std::string gtpatch_ratios_markdown(const std::vector<Group>& groups,
                                    const std::vector<std::uint64_t>& seeds) {
  const bool by_seed = seeds.size() > 1;
  std::ostringstream md;
  for (const Group& reference : groups) {
    if (reference.method != "gtpatch") continue;
    for (const Group& g : groups) {
      if (g.object != reference.object || g.method == "gtpatch") continue;
      if (md.tellp() == 0) {
        md << "\nMedian final error over GroundtruthPatch's (gtpatch, the object's model):\n\n"
              "| object | method | translation | rotation |"
           << (by_seed ? " translation by seed | rotation by seed |\n|---|---|---:|---:|---|---|\n"
                       : "\n|---|---|---:|---:|\n");
      }
      const auto ratios = [](const Group& value, const Group& ref) {
        return std::pair{
            ratio_cell(quantile(value.translation, 0.5), quantile(ref.translation, 0.5)),
            ratio_cell(quantile(value.rotation, 0.5), quantile(ref.rotation, 0.5))};
      };
      const auto [t, r] = ratios(g, reference);
      md << "| " << markdown_cell(g.object) << " | " << g.method << " | " << t << " | " << r
         << " |";
      if (by_seed) {
        std::string t_seeds, r_seeds;
        for (const std::uint64_t seed : seeds) {
          const auto [ts, rs] = ratios(g.of_seed(seed), reference.of_seed(seed));
          t_seeds += (t_seeds.empty() ? "" : " / ") + ts;
          r_seeds += (r_seeds.empty() ? "" : " / ") + rs;
        }
        md << " " << t_seeds << " | " << r_seeds << " |";
      }
      md << "\n";
    }
  }
  return md.str();
}

// With several eval seeds, each object and method's median final errors seed by seed.
std::string seed_medians_markdown(const std::vector<Group>& groups,
                                  const std::vector<std::uint64_t>& seeds) {
  if (seeds.size() < 2) return "";
  std::ostringstream md;
  md << "\nMedian final error by noise seed (--seeds), translation [mm] / rotation [rad]:\n\n"
        "| object | method |";
  for (const std::uint64_t seed : seeds) md << " seed " << seed << " |";
  md << "\n|---|---|";
  for (std::size_t k = 0; k < seeds.size(); ++k) md << "---|";
  md << "\n";
  char cell[64];
  for (const Group& g : groups) {
    md << "| " << markdown_cell(g.object) << " | " << g.method << " |";
    for (const std::uint64_t seed : seeds) {
      const Group s = g.of_seed(seed);
      std::snprintf(cell, sizeof cell, " %.3f / %.4f |", quantile(s.translation, 0.5) * 1e3,
                    quantile(s.rotation, 0.5));
      md << cell;
    }
    md << "\n";
  }
  return md.str();
}

// The runs the tracker warned about (track_warnings), by object, method and warning, with the
// first three runs' folders: which sequences to look at; empty when no run warned.
std::string warnings_markdown(const std::vector<Row>& rows,
                              const std::vector<std::string>& methods) {
  struct Warned {
    int runs = 0;
    std::string names;
  };
  std::map<std::string, std::map<std::string, int>> runs;  // object -> method -> runs
  // object -> method -> warning -> its runs
  std::map<std::string, std::map<std::string, std::map<std::string, Warned>>> by;
  for (const Row& r : rows) {
    ++runs[r.object][r.method];
    for (const std::string& warning : r.warnings) {
      Warned& w = by[r.object][r.method][warning];
      if (++w.runs <= 3) w.names += (w.names.empty() ? "" : ", ") + markdown_cell(r.run);
    }
  }
  if (by.empty()) return {};
  std::ostringstream md;
  md << "\nRuns the tracker warned about (each run's summary.json `warnings`, results.csv "
        "`warnings`; docs/outputs.md):\n\n| object | method | warning | runs "
        "|\n|---|---|---|---|\n";
  for (const auto& [object, per_method] : by) {
    for (const std::string& m : methods) {
      const auto it = per_method.find(m);
      if (it == per_method.end()) continue;
      for (const auto& [warning, w] : it->second) {
        md << "| " << markdown_cell(object) << " | " << m << " | " << warning << " | " << w.runs
           << " of " << runs[object][m] << ": " << w.names << (w.runs > 3 ? ", ..." : "") << " |\n";
      }
    }
  }
  return md.str();
}

std::string summary_markdown(const std::vector<Group>& groups,
                             const std::vector<std::uint64_t>& seeds) {
  std::ostringstream md;
  md << "| object | method | runs | final translation [mm] median (q1-q3) | final rotation [rad] "
        "median (q1-q3) | median update [ms] |\n|---|---|---:|---|---|---:|\n";
  char line[512];
  for (const Group& g : groups) {
    const auto& t = g.translation;
    const auto& rot = g.rotation;
    std::snprintf(
        line, sizeof(line), "| %s | %s | %zu | %.3f (%.3f-%.3f) | %.4f (%.4f-%.4f) | %.2f |\n",
        markdown_cell(g.object).c_str(), g.method.c_str(), t.size(), quantile(t, 0.5) * 1e3,
        quantile(t, 0.25) * 1e3, quantile(t, 0.75) * 1e3, quantile(rot, 0.5), quantile(rot, 0.25),
        quantile(rot, 0.75), quantile(g.ms, 0.5));
    md << line;
  }
  md << seed_medians_markdown(groups, seeds);
  md << gtpatch_ratios_markdown(groups, seeds);
  return md.str();
}

// Whether `folder` holds nothing but a track run's outputs (write_track_outputs'), whole or
// partly written (an eval stopped while writing them), or their temporary files.
bool is_track_run(const fs::path& folder) {
  std::error_code ec;
  if (!fs::is_directory(fs::symlink_status(folder, ec))) return false;
  for (const auto& entry : fs::directory_iterator(folder, ec)) {
    const std::string name = entry.path().filename().string();
    const bool output = std::any_of(
        kTrackOutputFiles.begin(), kTrackOutputFiles.end(),
        [&](const std::string& o) { return name == o || name.rfind(o + ".tmp.", 0) == 0; });
    if (!output || !fs::is_regular_file(entry.symlink_status())) return false;
  }
  return true;
}

// Throws InputError unless OUT/runs, which eval replaces, is absent or an earlier eval's: only
// track runs' folders. A folder of the user's of that name (or datasets given to this eval kept
// there) is not removed.
void check_runs_folder_is_evals(const std::string& out) {
  const fs::path runs = fs::path(out) / "runs";
  std::error_code ec;
  if (!fs::exists(fs::symlink_status(runs, ec))) return;
  const auto refuse = [&](const std::string& why) {
    throw InputError(runs.string() + ": " + why +
                     ", not an earlier eval's runs, which eval would replace; give another --out");
  };
  if (!fs::is_directory(fs::symlink_status(runs, ec))) refuse("is not a folder");
  for (const auto& entry : fs::directory_iterator(runs, ec)) {
    if (!is_track_run(entry.path())) refuse("holds " + entry.path().filename().string());
  }
}

// Lets go of what several runs share (a sequence's kept frames, an object's model) after the last
// of them, whether it ended well or not: counts its run down under the lock. Without a count it
// does nothing.
template <class T>
class LastRunLetsGo {
 public:
  LastRunLetsGo(std::mutex& lock, std::size_t* left, std::shared_ptr<T>* held)
      : lock_(lock), left_(left), held_(held) {}
  LastRunLetsGo(const LastRunLetsGo&) = delete;
  LastRunLetsGo& operator=(const LastRunLetsGo&) = delete;
  ~LastRunLetsGo() {
    if (!left_) return;
    const std::lock_guard<std::mutex> hold(lock_);
    if (--*left_ == 0) held_->reset();
  }

 private:
  std::mutex& lock_;
  std::size_t* left_;
  std::shared_ptr<T>* held_;
};

}  // namespace

int run_eval(const EvalArgs& args) {
  const std::vector<std::string> datasets = expand_datasets(args.datasets);
  std::vector<std::string> methods = args.methods.empty() ? method_names() : args.methods;
  for (const std::string& m : methods) method_from_string(m);  // fail before any work
  const std::vector<std::uint64_t> seeds =
      args.seeds.empty() ? std::vector<std::uint64_t>{args.track.seed} : args.seeds;
  const bool several_seeds = seeds.size() > 1;
  std::vector<std::string> names;
  as_usage_error([&] {
    check_names_given_once(methods, "--methods");
    std::vector<std::string> seed_names;
    for (const std::uint64_t seed : seeds) seed_names.push_back(std::to_string(seed));
    check_names_given_once(seed_names, "--seeds");
    names = run_names(datasets);
  });
  const bool gtpatch = std::find(methods.begin(), methods.end(), "gtpatch") != methods.end();
  // The models, loaded once for every run; each sequence's datasets (one per sensor) checked
  // against them before any work.
  const NormalsModels models = load_normals_models(args.track);
  std::vector<std::vector<Dataset>> opened;
  std::vector<std::string> model_keys;  // gtpatch's: each sequence's object_model_key
  std::set<std::string> meshes_checked;
  for (const auto& dir : datasets) {
    check_output_is_not_input(args.out, dir, "the dataset");
    opened.push_back(open_sequence(dir));
    const std::vector<const Dataset*> sensors = dataset_pointers(opened.back());
    check_normals_models(args.track.normals, models, sensors, args.track.blend_shading > 0);
    if (gtpatch) {
      // Its mesh found before any run, not after; once for the sequences of one object.
      model_keys.push_back(object_model_key(*sensors[0]));
      if (meshes_checked.insert(model_keys.back()).second) load_object_mesh(*sensors[0]);
    }
    note_missing_frames(sensors);
    note_long_batch(args.track, *sensors[0]);
    const std::vector<FramePose> truth = sequence_poses(sensors);
    if (!truth.empty() && !truth.back().object_known) {
      throw InputError(sensors[0]->dir() + "/poses.csv" +
                       (sensors.size() > 1 ? " (and the other sensors')" : "") +
                       ": no object pose at the last frame; eval compares final errors against "
                       "ground truth (track runs without it)");
    }
  }
  check_runs_folder_is_evals(args.out);
  // With --resume the earlier runs stay; the rest is written again at the end.
  std::vector<std::string> outputs = {"results.csv", "summary.md", "boxplots.png",
                                      "trajectories_*.png"};
  if (!args.resume) outputs.push_back("runs/");
  // An earlier eval's folder: its results.csv (the header's start, which no version changed), or
  // the runs/ (checked above) of one stopped before writing it.
  const EarlierRun earlier_eval = {
      "results.csv or runs/ of an earlier eval", [](const fs::path& folder) {
        std::error_code ec;
        return file_starts_with(folder / "results.csv", "dataset,object,method,") ||
               fs::is_directory(fs::symlink_status(folder / "runs", ec));
      }};
  const OutputFolder out(args.out, outputs, earlier_eval);
  // The runs in the order results.csv lists them: seed by seed, then dataset by dataset and
  // method by method. They run sequence by sequence, so that its runs (methods and seeds) take
  // its frames, decoded and read by the model once, from memory (PreparedFrames), which is let
  // go after its last run.
  struct Task {
    std::size_t seed;  // index into seeds
    std::size_t sequence;
    std::string method;
  };
  std::vector<Task> tasks;
  for (std::size_t s = 0; s < seeds.size(); ++s)
    for (std::size_t k = 0; k < opened.size(); ++k)
      for (const auto& m : methods) tasks.push_back({s, k, m});
  const auto run_name = [&](const Task& task) {
    return names[task.sequence] + "_" + task.method +
           (several_seeds ? "_seed" + std::to_string(seeds[task.seed]) : std::string());
  };
  // A task's tracking options; the seed mixed with the dataset's folder name, whatever other
  // datasets run with it (the run's name adds the parent folder's where two share a name).
  // `object`: gtpatch's object model (object_model), built once for the sequence's runs.
  const auto task_options = [&](const Task& task, const NormalsModels& job_model,
                                std::shared_ptr<const PointCloudTree> object) {
    const std::vector<const Dataset*> sensors = dataset_pointers(opened[task.sequence]);
    TrackArgs a = args.track;
    a.method = task.method;
    a.seed = sequence_seed(seeds[task.seed], as_given(datasets[task.sequence]).filename().string());
    return make_track_options(a, sensors, job_model, std::move(object));
  };
  // A task's row in results.csv.
  const auto row_for = [&](const Task& task, const TrackSummary& summary,
                           std::vector<std::string> warnings) {
    return Row{datasets[task.sequence],
               opened[task.sequence][0].info().object_name,
               task.method,
               "runs/" + run_name(task),
               seeds[task.seed],
               summary,
               std::move(warnings)};
  };
  std::vector<std::optional<Row>> finished(tasks.size());
  // --resume: an earlier eval's run of the same settings is kept (kept_track_run).
  int kept = 0;
  for (std::size_t i = 0; i < tasks.size() && args.resume; ++i) {
    const Task& task = tasks[i];
    const std::vector<const Dataset*> sensors = dataset_pointers(opened[task.sequence]);
    // The settings compared do not hold gtpatch's object model: an empty stand-in instead of
    // the mesh sampled.
    static const auto kNoModel = std::make_shared<const PointCloudTree>(PointCloud());
    const std::optional<KeptRun> earlier =
        kept_track_run(sensors, task_options(task, models, kNoModel),
                       (fs::path(args.out) / "runs" / run_name(task)).string());
    if (!earlier) continue;
    finished[i] = row_for(task, earlier->summary, earlier->warnings);
    ++kept;
  }
  std::vector<std::size_t> order;  // the runs to track
  for (std::size_t i = 0; i < tasks.size(); ++i)
    if (!finished[i]) order.push_back(i);
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return tasks[a].sequence < tasks[b].sequence;
  });
  if (args.resume && !args.track.quiet) {
    std::fprintf(stderr,
                 "--resume: %d of %zu runs kept from the earlier eval in %s, %zu to track\n", kept,
                 tasks.size(), args.out.c_str(), order.size());
  }
  const int jobs = int(std::clamp<std::size_t>(
      args.jobs > 0 ? std::size_t(args.jobs) : std::max(1u, std::thread::hardware_concurrency()), 1,
      std::max<std::size_t>(1, order.size())));
  // A sequence's frames are kept while its runs last when it has more than one run to track and
  // its frames fit a share of kPreparedFramesBytes (as many sequences as jobs, and one more, may
  // be kept at once): a 300-frame 120x160 sequence takes about 70 MB, 85 MB with colour for a
  // model.
  constexpr double kPreparedFramesBytes = 1024.0 * 1024 * 1024;
  std::vector<std::shared_ptr<PreparedFrames>> prepared(opened.size());
  std::vector<std::size_t> runs_left(opened.size(), 0);
  for (const std::size_t i : order) ++runs_left[tasks[i].sequence];
  // gtpatch's object models by object_model_key: one for every sequence of an object, built by
  // its first gtpatch run and let go after its last. Every key is in place before the jobs
  // start, which change only the values, under the lock.
  std::map<std::string, std::shared_ptr<const PointCloudTree>> object_models;
  std::map<std::string, std::size_t> model_runs_left;
  for (const std::size_t i : order) {
    if (tasks[i].method != "gtpatch") continue;
    ++model_runs_left[model_keys[tasks[i].sequence]];
    object_models[model_keys[tasks[i].sequence]];
  }
  for (std::size_t k = 0; k < opened.size(); ++k) {
    double bytes = 0;
    for (const Dataset& d : opened[k])
      bytes += double(d.frames()) * d.info().width() * d.info().height() *
               (3 * sizeof(float) + (args.track.normals == "gt" ? 0 : 3));
    if (runs_left[k] > 1 && bytes <= kPreparedFramesBytes / (jobs + 1))
      prepared[k] = make_prepared_frames();
  }
  // A model per job beyond the first: each job runs its own network.
  std::vector<NormalsModels> job_models{models};
  for (int j = 1; j < jobs && !models.empty(); ++j)
    job_models.push_back(load_normals_models(args.track));
  const int total = int(order.size());
  const std::string results = (fs::path(args.out) / "results.csv").string();
  // Progress over every run's frames: a long sequence is minutes of tracking between two of the
  // per-run lines. On a terminal each per-run line first clears the progress line it follows.
  long total_frames = 0, frames_done = 0;
  for (const std::size_t i : order) total_frames += long(opened[tasks[i].sequence][0].frames());
  Progress progress("tracking", int(std::min<long>(total_frames, INT_MAX)), !args.track.quiet);
  const bool tty = isatty(fileno(stderr));
  // The jobs take the runs in order; the progress, the lines and the first failure under one
  // lock. A run's row lands in its own slot, so results.csv's order is the tasks' whatever the
  // order the runs end in.
  std::vector<long> run_frames(tasks.size(), 0);
  std::mutex lock;
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr failure;
  int done = 0;
  auto run_task = [&](std::size_t i, const NormalsModels& job_model) {
    const Task& task = tasks[i];
    // A gtpatch run's object model, and its count of the runs that still need it.
    std::shared_ptr<const PointCloudTree>* model = nullptr;
    std::size_t* model_left = nullptr;
    if (task.method == "gtpatch") {
      model = &object_models.at(model_keys[task.sequence]);
      model_left = &model_runs_left.at(model_keys[task.sequence]);
    }
    const LastRunLetsGo<PreparedFrames> let_frames_go(lock, &runs_left[task.sequence],
                                                      &prepared[task.sequence]);
    const LastRunLetsGo<const PointCloudTree> let_model_go(lock, model_left, model);
    const std::vector<const Dataset*> sensors = dataset_pointers(opened[task.sequence]);
    const Dataset& dataset = *sensors[0];
    std::shared_ptr<PreparedFrames> frames;
    std::shared_ptr<const PointCloudTree> object;
    {
      const std::lock_guard<std::mutex> hold(lock);
      frames = prepared[task.sequence];
      // gtpatch's model built by the object's first gtpatch run (the others wait for it).
      if (model) {
        if (!*model) *model = object_model(dataset);
        object = *model;
      }
    }
    TrackOptions options = task_options(task, job_model, object);
    options.prepared_frames = frames;
    const TrackRun run = track_dataset(sensors, options, [&](int frame, int) {
      const std::lock_guard<std::mutex> hold(lock);
      frames_done += frame - run_frames[i];
      run_frames[i] = frame;
      progress.update(int(std::min<long>(frames_done, INT_MAX)));
    });
    const std::string name = run_name(task);
    const fs::path run_dir = fs::path(args.out) / "runs" / name;
    try {
      write_track_outputs(run, sensors, run_dir.string());
    } catch (const InputError&) {
      // A run whose outputs could not all be written (a full disk) leaves none of them, and no
      // empty runs folder (eval's own: it replaces them).
      std::error_code ec;
      fs::remove_all(run_dir, ec);
      if (fs::is_empty(run_dir.parent_path(), ec)) fs::remove(run_dir.parent_path(), ec);
      throw;
    }
    finished[i] = row_for(task, run.summary, track_warnings(run.summary));
    const std::lock_guard<std::mutex> hold(lock);
    frames_done += dataset.frames() - run_frames[i];
    run_frames[i] = dataset.frames();
    ++done;
    if (!args.track.quiet) {
      std::fprintf(stderr, "%s[%d/%d] %s %s: final %.3f mm %.4f rad, %.0f Hz\n",
                   tty ? "\r\033[K" : "", done, total, name.c_str(),
                   dataset.info().object_name.c_str(), run.summary.final_translation_error_m * 1e3,
                   run.summary.final_rotation_error_rad, run.summary.hz);
    }
  };
  // A failure (a damaged frame file, Ctrl-C) stops every job from starting another run; the
  // runs already going finish (or stop at the signal too).
  auto work = [&](const NormalsModels& job_model) {
    while (!failed) {
      const std::size_t n = next++;
      if (n >= order.size()) return;
      try {
        run_task(order[n], job_model);
      } catch (...) {
        const std::lock_guard<std::mutex> hold(lock);
        if (!failure) failure = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<Row> rows;
  try {
    const StopOnSignals stop;
    std::vector<std::thread> threads;
    try {
      for (int j = 0; j < jobs && jobs > 1; ++j)
        threads.emplace_back(work, std::cref(job_models[std::size_t(j) % job_models.size()]));
    } catch (const std::system_error&) {
      // The system gave fewer threads than asked for: those made share the runs.
    }
    if (threads.empty()) work(job_models[0]);
    for (std::thread& t : threads) t.join();
    for (auto& row : finished)
      if (row) rows.push_back(std::move(*row));
    if (failure) std::rethrow_exception(failure);
  } catch (const InputError& e) {
    // A dataset that fails half-way (a damaged frame file) keeps the runs finished before it.
    if (rows.empty()) throw;
    write_results_csv(results, rows);
    throw InputError(std::string(e.what()) + "\n(eval stopped there; " + results + " holds the " +
                     std::to_string(rows.size()) + " run(s) finished before it)");
  } catch (const Stopped& e) {
    // Ctrl-C on a long matrix keeps what it measured; the runs cut short are not among them.
    if (rows.empty()) throw e.with_note("no run finished; nothing written");
    write_results_csv(results, rows);
    throw e.with_note(results + " holds the " + std::to_string(rows.size()) +
                      " run(s) finished before it (no summary.md or plots)");
  }
  write_results_csv(results, rows);
  // Runs that never registered anything: their errors are the first pose's prior's, which a gate
  // would pass (track says so of its one run).
  std::string untouched;
  int untouched_runs = 0;
  for (const Row& r : rows) {
    if (std::find(r.warnings.begin(), r.warnings.end(), "no_contact") == r.warnings.end()) continue;
    if (++untouched_runs <= 3) untouched += (untouched.empty() ? "" : ", ") + r.run;
  }
  if (untouched_runs > 0) {
    std::fprintf(stderr,
                 "warning: %d run(s) without any contact frame (%s%s): nothing was registered, "
                 "their errors are the first pose's prior's (results.csv: contact_frames)\n",
                 untouched_runs, untouched.c_str(), untouched_runs > 3 ? ", ..." : "");
  }
  const std::vector<Group> groups = group_runs(rows, methods);
  std::string md = summary_markdown(groups, seeds) + warnings_markdown(rows, methods);
  if (kept > 0) {
    md += "\n" + std::to_string(kept) + " of the " + std::to_string(tasks.size()) +
          " runs kept from an earlier eval into this folder (--resume): their update times are "
          "that eval's.\n";
  }
  if (jobs > 1) {
    md += "\nRuns tracked " + std::to_string(jobs) +
          " at once (--jobs): their update times shared the machine's cores, so the median "
          "update and Hz read slower than one run alone; the errors do not change.\n";
  }
  write_text_atomically((fs::path(args.out) / "summary.md").string(), md);
  std::printf("%s", md.c_str());
  std::printf("wrote %s and %s\n", results.c_str(), (fs::path(args.out) / "summary.md").c_str());
  if (!args.no_plots) run_plot_script("plot_eval.py", args.out);
  std::fflush(stdout);
  bool within = true;
  for (const Group& g : groups) {
    within &= within_accuracy_gate(args.track, g.object + " " + g.method + " (median)",
                                   quantile(g.translation, 0.5), quantile(g.rotation, 0.5));
  }
  return within ? kExitOk : kExitAccuracy;
}

}  // namespace pg
