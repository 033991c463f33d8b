#include "bench.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <tuple>
#include <utility>

#include "../common/cli_main.h"
#include "../common/machine_info.h"
#include "../common/plot_script.h"
#include "bench_cache.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/graph/track_dataset.h"
#include "track_args.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

// One point of the sweep: the default configuration with one knob changed.
struct Setting {
  std::string knob = "default";  // which knob differs from the default
  std::string value = "-";
  int width = 120, height = 160;
  std::string method = "patchgraph";
  std::string normals = "gt";
  int keyframe_interval = TrackArgs().keyframe_interval;
  int keyframe_settle = TrackArgs().keyframe_settle;  // PatchMapOptions::keyframe_settle_frames
  int window = TrackArgs().window;
  bool registration_information = true;
  int icp_iterations = IcpOptions().max_iterations;
  double max_correspondence_m = IcpOptions().max_correspondence_m;
  double voxel_m = IcpOptions().voxel_size_m;
  // 0 / 1: the symmetric ICP objective off / on; -1: as `track` sets it for the normals source
  // (resolved to 0 or 1 before the sweep runs).
  int icp_symmetric = -1;
  // IcpOptions::max_normal_angle_rad (0: every pair, whatever its normals)
  double max_normal_angle_rad = IcpOptions().max_normal_angle_rad;
  bool contact_core = true;  // false: the cloud is always the whole contact
  // 0 / 1: the averaged / parity integration of the normals; -1: as `track` sets it for the
  // normals source (resolved before the sweep runs, as icp_symmetric).
  int parity_integration = -1;
  // false: GraphOptions::image_to_image_gate_rad 0 (resolved, as icp_symmetric, to what `track`
  // sets for the normals source: off for a model)
  bool image_to_image_gate = true;

  std::string name() const { return knob == "default" ? "default" : knob + " " + value; }
};

std::string fmt(const char* format, double v) {
  char text[64];
  std::snprintf(text, sizeof(text), format, v);
  return text;
}

std::vector<Setting> sweep(const TrackBenchArgs& args) {
  const Setting base;
  std::vector<Setting> out = {base};
  auto add = [&](const std::string& knob, const std::string& value, auto&& change) {
    Setting s = base;
    s.knob = knob;
    s.value = value;
    change(s);
    out.push_back(s);
  };
  add("resolution", "240x320", [](Setting& s) { s.width = 240, s.height = 320; });
  if (!args.quick) {
    for (int k : {5, 20, 40}) {
      add("keyframe interval", std::to_string(k), [&](Setting& s) { s.keyframe_interval = k; });
    }
    for (int n : {3, 5, 10}) {
      add("ICP iterations", std::to_string(n), [&](Setting& s) { s.icp_iterations = n; });
    }
    for (double mm : {0.5, 2.0, 4.0}) {
      add("correspondence", fmt("%g mm", mm),
          [&](Setting& s) { s.max_correspondence_m = mm * 1e-3; });
    }
  }
  for (double mm : args.quick ? std::vector<double>{0.2} : std::vector<double>{0.1, 0.2, 0.4}) {
    add("voxel", fmt("%g mm", mm), [&](Setting& s) { s.voxel_m = mm * 1e-3; });
  }
  for (int w : args.quick ? std::vector<int>{3} : std::vector<int>{2, 3, 10, 20}) {
    add("window", std::to_string(w), [&](Setting& s) { s.window = w; });
  }
  add("registration information", "off", [](Setting& s) { s.registration_information = false; });
  if (!args.quick) {
    add("ICP objective", "target normals", [](Setting& s) { s.icp_symmetric = 0; });
    add("pairs' normals limit", "off", [](Setting& s) { s.max_normal_angle_rad = 0; });
    add("key-frame settling", "4 frames", [](Setting& s) { s.keyframe_settle = 4; });
    add("contact core", "off", [](Setting& s) { s.contact_core = false; });
    add("integration", "averaged", [](Setting& s) { s.parity_integration = 0; });
    add("image-to-image gate", "off", [](Setting& s) { s.image_to_image_gate = false; });
  }
  for (const char* m : args.quick ? std::vector<const char*>{"constvel"}
                                  : std::vector<const char*>{"constvel", "imagetoimage"}) {
    add("method", m, [&](Setting& s) { s.method = m; });
  }
  for (const auto& n : args.normals) {
    if (n != base.normals) add("normals", n, [&](Setting& s) { s.normals = n; });
  }
  return out;
}

std::vector<std::string> default_scenes(bool quick) {
  const std::string dir = std::string(PG_SOURCE_DIR) + "/scenes/benchmark/";
  if (quick) return {dir + "cube_00.json", dir + "toy_brick_00.json"};
  std::vector<std::string> out;
  for (const char* object : {"cube", "sphere", "toy_brick", "toy_human"}) {
    for (const char* seq : {"00", "01", "02"}) out.push_back(dir + object + "_" + seq + ".json");
  }
  return out;
}

struct RunResult {
  std::string scene, object;
  std::string dataset;  // the render in the cache that was tracked
  TrackSummary summary;
};

struct Row {
  Setting setting;
  std::vector<RunResult> runs;
  double median_ms = 0, final_t_m = 0, final_r_rad = 0, rmse_t_m = 0, rmse_r_rad = 0;
  bool front_t = false, front_r = false;  // on the time-vs-error Pareto front
};

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void summarise(Row& row) {
  std::vector<double> ms, t, r, rt, rr;
  for (const auto& run : row.runs) {
    ms.push_back(run.summary.median_frame_ms);
    t.push_back(run.summary.final_translation_error_m);
    r.push_back(run.summary.final_rotation_error_rad);
    rt.push_back(run.summary.translation_rmse_m);
    rr.push_back(run.summary.rotation_rmse_rad);
  }
  row.median_ms = median(ms);
  row.final_t_m = median(t);
  row.final_r_rad = median(r);
  row.rmse_t_m = median(rt);
  row.rmse_r_rad = median(rr);
}

// A row is on the front when no other row is at least as fast and at least as accurate, and
// strictly better in one of the two.
void mark_pareto(std::vector<Row>& rows) {
  auto dominated = [&](const Row& a, double Row::*err) {
    for (const Row& b : rows) {
      if (&a == &b) continue;
      if (b.median_ms <= a.median_ms && b.*err <= a.*err &&
          (b.median_ms < a.median_ms || b.*err < a.*err)) {
        return true;
      }
    }
    return false;
  };
  for (Row& row : rows) {
    row.front_t = !dominated(row, &Row::final_t_m);
    row.front_r = !dominated(row, &Row::final_r_rad);
  }
}

// A --normals row "MODEL+shading:W" is the model's normals averaged with the shading's inverse
// (track's --normals MODEL --blend-shading W, whose summary.json names its normals so): the model
// and W; any other row is its source and 0. Throws InputError for a W outside (0, 1] or a blend
// without a model.
constexpr const char* kBlendMark = "+shading:";
std::pair<std::string, double> split_blend(const std::string& source) {
  const std::size_t at = source.rfind(kBlendMark);
  if (at == std::string::npos) return {source, 0.0};
  const std::string model = source.substr(0, at);
  const std::string weight = source.substr(at + std::string(kBlendMark).size());
  double w = 0;
  std::size_t used = 0;
  try {
    w = std::stod(weight, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != weight.size() || !(w > 0 && w <= 1)) {
    throw InputError("--normals " + source + ": the shading's weight must be a number in (0, 1], " +
                     "got '" + weight + "'");
  }
  if (model.empty() || model == "gt" || model == kShadingNormals) {
    throw InputError("--normals " + source + ": averages a model's normals with the shading's " +
                     "inverse; give MODEL+shading:W");
  }
  return {model, w};
}

TrackArgs args_for(const Setting& s, std::uint64_t seed) {
  TrackArgs a;
  a.seed = seed;
  a.method = s.method;
  // The same source as `patchgraph track --normals` (and --blend-shading).
  std::tie(a.normals, a.blend_shading) = split_blend(s.normals);
  a.window = s.window;
  a.keyframe_interval = s.keyframe_interval;
  a.keyframe_settle = s.keyframe_settle;
  a.no_registration_information = !s.registration_information;
  if (!s.image_to_image_gate) a.image_to_image_gate = 0;
  return a;
}

// The --normals models, each source loaded once, by its name.
using Models = std::map<std::string, NormalsModels>;

TrackOptions options_for(const Setting& s, const Dataset& dataset, std::uint64_t seed,
                         const Models& models) {
  TrackOptions o = make_track_options(args_for(s, seed), {&dataset}, models.at(s.normals));
  // One thread, frame after frame: what bench measures is the update, with nothing beside it
  // (and --threads is the threads it uses).
  o.prefetch = false;
  o.front_end.icp.max_iterations = s.icp_iterations;
  o.front_end.icp.max_correspondence_m = s.max_correspondence_m;
  o.front_end.icp.voxel_size_m = s.voxel_m;
  if (s.icp_symmetric >= 0) o.front_end.icp.symmetric = s.icp_symmetric == 1;
  o.front_end.icp.max_normal_angle_rad = s.max_normal_angle_rad;
  if (!s.contact_core) o.front_end.mask.core_relative_depth = 0.0;
  if (s.parity_integration >= 0) {
    o.front_end.depth.integration =
        s.parity_integration == 1 ? DepthIntegration::kParity : DepthIntegration::kAveraged;
  }
  return o;
}

void write_csv(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream out = open_for_writing(path);
  out.precision(9);
  out << "setting,knob,value,method,normals,width,height,keyframe_interval,keyframe_settle,window,"
         "registration_information,icp_iterations,max_correspondence_m,voxel_m,icp_symmetric,"
         "icp_max_normal_angle_rad,contact_core,depth_integration,image_to_image_gate,runs,"
         "median_frame_ms,median_final_translation_m,median_final_rotation_rad,"
         "median_translation_rmse_m,median_rotation_rmse_rad,pareto_translation,pareto_rotation\n";
  for (const Row& r : rows) {
    const Setting& s = r.setting;
    out << csv_field(s.name()) << "," << s.knob << "," << csv_field(s.value) << "," << s.method
        << "," << csv_field(s.normals) << "," << s.width << "," << s.height << ","
        << s.keyframe_interval << "," << s.keyframe_settle << "," << s.window << ","
        << s.registration_information << "," << s.icp_iterations << "," << s.max_correspondence_m
        << "," << s.voxel_m << "," << s.icp_symmetric << "," << s.max_normal_angle_rad << ","
        << s.contact_core << "," << (s.parity_integration == 1 ? "parity" : "averaged") << ","
        << s.image_to_image_gate << "," << r.runs.size() << "," << r.median_ms << "," << r.final_t_m
        << "," << r.final_r_rad << "," << r.rmse_t_m << "," << r.rmse_r_rad << "," << r.front_t
        << "," << r.front_r << "\n";
  }
  close_checked(out, path);
}

void write_runs_csv(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream out = open_for_writing(path);
  out.precision(9);
  out << "setting,scene,object,frames,final_translation_error_m,final_rotation_error_rad,"
         "translation_rmse_m,rotation_rmse_rad,median_frame_ms,rejected_registrations,dataset,"
         "seed\n";
  for (const Row& r : rows) {
    for (const RunResult& run : r.runs) {
      const TrackSummary& s = run.summary;
      out << csv_field(r.setting.name()) << "," << csv_field(run.scene) << ","
          << csv_field(run.object) << "," << s.frames << "," << s.final_translation_error_m << ","
          << s.final_rotation_error_rad << "," << s.translation_rmse_m << "," << s.rotation_rmse_rad
          << "," << s.median_frame_ms << "," << s.rejected_registrations << ","
          << csv_field(run.dataset) << "," << s.seed << "\n";
    }
  }
  close_checked(out, path);
}

std::string markdown_table(const std::vector<Row>& rows) {
  std::ostringstream md;
  md << "| setting | median update [ms] | final translation [mm] | final rotation [rad] | "
        "translation RMSE [mm] | rotation RMSE [rad] | Pareto front |\n"
        "|---|---:|---:|---:|---:|---:|---|\n";
  for (const Row& r : rows) {
    char line[512];
    const std::string front = r.front_t && r.front_r ? "translation, rotation"
                              : r.front_t            ? "translation"
                              : r.front_r            ? "rotation"
                                                     : "";
    std::snprintf(line, sizeof(line), "| %s | %.2f | %.3f | %.4f | %.3f | %.4f | %s |\n",
                  r.setting.name().c_str(), r.median_ms, r.final_t_m * 1e3, r.final_r_rad,
                  r.rmse_t_m * 1e3, r.rmse_r_rad, front.c_str());
    md << line;
  }
  return md.str();
}

std::string command(const TrackBenchArgs& a, bool default_scenes_used) {
  std::string cmd = "patchgraph bench --out " + a.out;
  if (a.quick) cmd += " --quick";
  if (a.frames > 0) cmd += " --frames " + std::to_string(a.frames);
  if (a.threads > 0) cmd += " --threads " + std::to_string(a.threads);
  if (a.normals.size() != 1 || a.normals[0] != "gt") {
    cmd += " --normals";
    for (const auto& n : a.normals) cmd += " " + n;
  }
  if (!default_scenes_used) cmd += " --scenes ...";
  return cmd;
}

}  // namespace

int run_track_bench(const TrackBenchArgs& in) {
  TrackBenchArgs args = in;
  const bool own_scenes = !args.scenes.empty();
  if (!own_scenes) args.scenes = default_scenes(args.quick);
  // Given twice, a scene or normals source would count twice in every median (a usage error, as
  // in track and eval).
  as_usage_error([&] {
    check_given_once(args.scenes);
    // "gt", "shading", or a model file however its path is written.
    std::map<std::string, std::string> seen;
    for (const std::string& n : args.normals) {
      const auto [model, weight] = split_blend(n);
      const std::string key =
          model == "gt" || model == kShadingNormals ? model : fs::weakly_canonical(model).string();
      const auto [it, fresh] =
          seen.emplace(weight > 0 ? key + kBlendMark + format_number(weight) : key, n);
      if (!fresh) throw InputError("--normals: " + n + " given twice (also as " + it->second + ")");
    }
  });
  const int given_frames = args.frames;  // --quick's 60 cuts a shorter scene to its own length
  if (args.quick && args.frames == 0) args.frames = 60;
  if (args.cache.empty()) args.cache = (fs::path(args.out) / "cache").string();
  // The cache's entries are datasets of their own, not files to mix into another's folder.
  check_output_is_no_dataset(args.cache, false, "--cache");
  std::unique_ptr<tbb::global_control> limit;
  if (args.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  args.threads);
  }
  std::vector<Setting> settings = sweep(args);
  // Learned normals read the colour images; ground truth only the normal images.
  std::vector<std::string> outputs = {"normal"};
  for (const auto& s : settings) {
    if (s.normals != "gt" && outputs.size() == 1) outputs.push_back("color");
  }
  // An earlier bench's folder: its bench.csv or runs.csv (their headers' start).
  const EarlierRun earlier_bench = {
      "bench.csv or runs.csv of an earlier bench", [](const fs::path& folder) {
        return file_starts_with(folder / "bench.csv", "setting,knob,value,") ||
               file_starts_with(folder / "runs.csv", "setting,scene,object,");
      }};
  const OutputFolder out(args.out, {"bench.csv", "bench.md", "runs.csv", "bench.png"},
                         earlier_bench);
  const std::string head = "Command: `" + command(in, !own_scenes) + "`  \n" + machine_line() +
                           "  \nDate: " + utc_now() + "  \n" + std::to_string(args.scenes.size()) +
                           " scenes x " + std::to_string(settings.size()) +
                           " settings; per setting the median over the scenes of: each run's "
                           "median per-frame update time, its final errors and its RMSE.\n\n";
  // Every scene read and every model loaded before anything is rendered, then every setting's
  // options once on the first scene before any tracking: a bad scene, normals source (or any
  // other option) fails now rather than after the sweep's first scene.
  const StopOnSignals stop;
  std::vector<BenchScene> scenes;
  for (const auto& path : args.scenes) {
    scenes.push_back(check_bench_scene(path));
    if (given_frames > scenes.back().scene.frames) {  // as tacsim render --frames says it
      throw UsageError("--frames " + std::to_string(given_frames) + ": " + path + " has " +
                       std::to_string(scenes.back().scene.frames) + " frames");
    }
  }
  Models models;
  for (const auto& s : settings) {
    if (!models.count(s.normals)) models[s.normals] = load_normals_models(args_for(s, 0));
  }
  stop_if_asked();  // before the first render starts an entry
  const auto dataset_for = [&](const BenchScene& scene, const Setting& s) {
    return Dataset::open(
        cached_dataset(scene, s.width, s.height, args.frames, outputs, args.cache));
  };
  // Tracking a cache entry whose files no longer read (one cut short): named, with what to do.
  const auto track_cached = [&](const Dataset& dataset, const TrackOptions& options) {
    try {
      return track_dataset(dataset, options, [](int, int) { stop_if_asked(); });
    } catch (const InputError& e) {
      const std::string what = e.what();
      if (what.find(dataset.dir()) == std::string::npos) throw;
      throw InputError(what + " (a render in the bench's cache: remove " + dataset.dir() +
                       " to render it again)");
    }
  };
  {
    const Dataset first = dataset_for(scenes.front(), Setting());
    for (const auto& [source, loaded] : models) {
      const auto [model, weight] = split_blend(source);
      check_normals_models(model, loaded, {&first}, weight > 0);
    }
    for (auto& s : settings) {
      // What `track` sets for the normals source, recorded as run.
      const TrackOptions o = options_for(s, first, 0, models);
      s.icp_symmetric = o.front_end.icp.symmetric;
      s.parity_integration = o.front_end.depth.integration == DepthIntegration::kParity;
      s.image_to_image_gate = o.graph.image_to_image_gate_rad > 0;
    }
  }
  // One untimed run first: the process's first tracking pays for allocations and FFT plans,
  // which would otherwise count against whichever setting comes first.
  try {
    const Dataset first = dataset_for(scenes.front(), settings.front());
    track_cached(first, options_for(settings.front(), first, 0, models));
  } catch (const Stopped& e) {
    throw e.with_note("nothing written to " + args.out);
  }
  std::vector<Row> rows(settings.size());
  for (std::size_t i = 0; i < settings.size(); ++i) rows[i].setting = settings[i];
  const int total = int(args.scenes.size() * settings.size());
  int done = 0;
  // The settings that read the same frames (one resolution and normals source) share them within
  // a scene: decoded, and read by a model, by the first and taken from memory by the rest (the
  // model's time as the first measured it, in each one's update). Let go after the last of them.
  const auto frames_key = [](const Setting& s) {
    return std::to_string(s.width) + "x" + std::to_string(s.height) + " " + s.normals;
  };
  for (const BenchScene& scene : scenes) {
    const std::string scene_name = fs::path(scene.path).stem().string();
    std::map<std::string, std::pair<std::shared_ptr<PreparedFrames>, int>> prepared;
    for (const Row& row : rows) ++prepared[frames_key(row.setting)].second;
    for (Row& row : rows) {
      const Setting& s = row.setting;
      auto& shared = prepared.at(frames_key(s));  // the frames, and the runs still to read them
      std::shared_ptr<PreparedFrames>& frames = shared.first;
      if (!frames && shared.second > 1) frames = make_prepared_frames();
      std::string dataset_dir;
      const TrackRun run = [&] {
        try {
          const Dataset dataset = dataset_for(scene, s);
          dataset_dir = dataset.dir();
          TrackOptions options = options_for(s, dataset, sequence_seed(0, scene_name), models);
          options.prepared_frames = frames;
          return track_cached(dataset, options);
        } catch (const Stopped& e) {
          throw e.with_note("nothing written to " + args.out + " (after " + std::to_string(done) +
                            " of " + std::to_string(total) + " runs)");
        }
      }();
      if (--shared.second == 0) frames.reset();
      const SceneObject& object = scene.scene.objects.at(std::size_t(scene.scene.tracked_object));
      row.runs.push_back({scene_name, object.name, dataset_dir, run.summary});
      ++done;
      if (!args.quiet) {
        std::fprintf(stderr, "[%d/%d] %s, %s: final %.3f mm %.4f rad, median %.2f ms\n", done,
                     total, scene_name.c_str(), s.name().c_str(),
                     run.summary.final_translation_error_m * 1e3,
                     run.summary.final_rotation_error_rad, run.summary.median_frame_ms);
      }
    }
  }
  // A scene without contact times prediction alone, the same for every setting.
  for (std::size_t k = 0; k < args.scenes.size(); ++k) {
    if (rows.front().runs[k].summary.contact_frames == 0) {
      std::fprintf(stderr,
                   "warning: %s: no contact in any frame: its runs time the motion prior alone, "
                   "the same for every setting\n",
                   args.scenes[k].c_str());
    }
  }
  for (Row& row : rows) summarise(row);
  mark_pareto(rows);
  const std::string csv = (fs::path(args.out) / "bench.csv").string();
  const std::string md_path = (fs::path(args.out) / "bench.md").string();
  write_csv(csv, rows);
  write_runs_csv((fs::path(args.out) / "runs.csv").string(), rows);
  const std::string md = head + markdown_table(rows);
  write_text_file(md_path, md);
  std::printf("%s", md.c_str());
  std::printf("wrote %s, %s and %s/runs.csv\n", csv.c_str(), md_path.c_str(), args.out.c_str());
  if (!args.no_plot && run_plot_script("plot_bench.py", args.out)) {
    std::printf("wrote %s/bench.png\n", args.out.c_str());
  }
  return 0;
}

}  // namespace pg
