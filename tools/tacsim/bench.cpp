#include "bench.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <memory>
#include <sstream>
#include <thread>

#include "../common/cli_main.h"
#include "../common/machine_info.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/statistics.h"
#include "pg/sim/primitives.h"
#include "pg/sim/renderer.h"

namespace pg {
namespace {

struct Case {
  std::string name;
  std::shared_ptr<const ObjectShape> shape;
  SE3 T_sensor_object;
};

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

struct Timing {
  double fps = 0;             // frames rendered in parallel, one per thread at a time
  double ms_one_thread = 0;   // latency of one frame rendered alone
  double contact_pixels = 0;
  double rays = 0;
  double triangles = 0;
};

// One case ready to time: its renderer, and a frame per thread to render into (reused from
// frame to frame, as a dataset writer would).
struct Run {
  std::unique_ptr<SensorRenderer> renderer;
  std::vector<SE3> poses;
  tbb::enumerable_thread_specific<RenderedFrame> frames;
  RenderedFrame frame;  // for the one-thread timing
  std::vector<double> fps, ms;
};

// One timed run of `frames` frames in parallel, then half as many on this thread alone.
void time_once(Run& run, int frames) {
  auto start = std::chrono::steady_clock::now();
  tbb::parallel_for(0, frames, [&](int f) {
    run.renderer->render(run.poses, std::uint64_t(f), run.frames.local());
  });
  run.fps.push_back(frames / seconds_since(start));
  const int n = std::max(1, frames / 2);
  start = std::chrono::steady_clock::now();
  for (int f = 0; f < n; ++f) run.renderer->render(run.poses, std::uint64_t(f), run.frame);
  run.ms.push_back(1e3 * seconds_since(start) / n);
}

// The cases of one resolution and shadow setting, their runs interleaved (a b c d a b c d ...)
// so that a change in the machine's load falls on every case alike and their ratios hold.
std::vector<Timing> time_cases(const std::vector<Case>& cases, const std::string& preset,
                               bool shadows, const BenchArgs& args) {
  RenderSettings settings;
  settings.depth = false;
  settings.mask = false;
  settings.shadows = shadows;
  std::vector<Run> runs(cases.size());
  std::vector<Timing> out(cases.size());
  for (std::size_t c = 0; c < cases.size(); ++c) {
    runs[c].renderer = std::make_unique<SensorRenderer>(sensor_preset(preset),
                                                        std::vector{cases[c].shape}, settings);
    runs[c].poses = {cases[c].T_sensor_object};
    runs[c].renderer->render(runs[c].poses, 0, runs[c].frame);
    const RenderStats& stats = runs[c].frame.stats;
    out[c].contact_pixels = stats.contact_pixels;
    out[c].rays = double(stats.rays_cast);
    out[c].triangles = double(stats.triangles_rasterized);
  }
  for (int r = 0; r < args.repeats; ++r)
    for (Run& run : runs) time_once(run, args.frames);
  for (std::size_t c = 0; c < cases.size(); ++c) {
    out[c].fps = upper_median(runs[c].fps);
    out[c].ms_one_thread = upper_median(runs[c].ms);
  }
  return out;
}

// The command line that reproduces this run.
std::string command(const BenchArgs& in) {
  std::string cmd = "tacsim bench";
  if (in.quick) cmd += " --quick";
  if (in.ablation) cmd += " --ablation";
  if (!in.ablation) cmd += " --frames " + std::to_string(in.frames);
  cmd += " --repeats " + std::to_string(in.repeats);
  if (in.threads > 0) cmd += " --threads " + std::to_string(in.threads);
  if (!in.markdown.empty()) cmd += " --markdown " + in.markdown;
  return cmd;
}

// The four cases.
std::vector<Case> bench_cases() {
  const auto sphere = std::make_shared<ObjectShape>(make_uv_sphere(0.006f, 72, 144));     // ~20k tris
  const auto dense = std::make_shared<ObjectShape>(make_uv_sphere(0.006f, 250, 400));     // 200k tris
  const auto slab = std::make_shared<ObjectShape>(make_box({0.015f, 0.015f, 0.005f}));
  return {
      {"(a) no contact: sphere r 6 mm, 5 mm above the gel", sphere, SE3::Translation({0, 0, 0.011})},
      {"(b) sphere r 6 mm pressed 1 mm", sphere, SE3::Translation({0, 0, 0.005})},
      {"(c) flat face pressed 1.5 mm (half the gel)", slab, SE3::Translation({0, 0, 0.0035})},
      {"(d) 200k-triangle sphere pressed 1 mm", dense, SE3::Translation({0, 0, 0.005})},
  };
}

// One skip of the renderer switched off (or, for "outputs", every output requested).
struct Variant {
  const char* name;
  void (*apply)(RenderSettings&);
};

const Variant kVariants[] = {
    {"all skips on (colour + normals)", [](RenderSettings&) {}},
    {"no culling", [](RenderSettings& s) { s.cull = false; }},
    {"no footprint (rays over the whole image)", [](RenderSettings& s) { s.footprint = false; }},
    {"rays from the camera, not the slab", [](RenderSettings& s) { s.slab_limited_rays = false; }},
    {"no no-contact cache", [](RenderSettings& s) { s.no_contact_cache = false; }},
    {"no rasterizer (rays only)", [](RenderSettings& s) { s.rasterize = false; }},
    // The slab limit matters where rays are cast: compare this row with the one above.
    {"rays only, from the camera", [](RenderSettings& s) { s.rasterize = s.slab_limited_rays = false; }},
    {"unrequested outputs too (+ depth, mask, contact points)",
     [](RenderSettings& s) { s.depth = s.mask = s.contact_points = true; }},
};

// Milliseconds per frame on this thread, rendering into a reused frame for about `budget_s`.
double time_frames(const SensorRenderer& renderer, const std::vector<SE3>& poses,
                   RenderedFrame& frame, double budget_s) {
  auto start = std::chrono::steady_clock::now();
  int n = 0;
  do {
    renderer.render(poses, std::uint64_t(n), frame);
    ++n;
  } while (seconds_since(start) < budget_s);
  return 1e3 * seconds_since(start) / n;
}

// Each skip switched off in turn: the cost of a frame (one thread) relative to the renderer with
// every skip on. The runs of one case are interleaved, as in the speed table.
int run_ablation(const std::vector<Case>& cases, const BenchArgs& args) {
  const double budget_s = args.quick ? 0.02 : 0.15;
  std::string report;  // the whole markdown file
  std::ostringstream out;
  out << "Command: `" << command(args) << "`  \n"
      << machine_line() << "  \n"
      << "Date: " << utc_now() << "  \n"
      << "One thread, noise on, rendering into a reused frame; ms per frame (median of "
      << args.repeats << " runs of about " << budget_s
      << " s each) and, in brackets, the cost relative to the first row.\n\n";
  for (const char* preset : {"digit", "digit_240x320"}) {
    const auto cam = sensor_preset(preset).camera;
    out << "**" << cam.width << "x" << cam.height << "**\n\n| skip switched off |";
    for (const Case& c : cases) out << " " << c.name.substr(0, 3) << " |";
    out << "\n|---|";
    for (std::size_t c = 0; c < cases.size(); ++c) out << "---:|";
    out << "\n";
    const int n_variants = int(std::size(kVariants));
    std::vector<std::vector<double>> ms(cases.size() * n_variants);
    std::vector<std::unique_ptr<SensorRenderer>> renderers(ms.size());
    std::vector<RenderedFrame> frames(ms.size());
    for (std::size_t c = 0; c < cases.size(); ++c) {
      for (int v = 0; v < n_variants; ++v) {
        RenderSettings settings;
        settings.depth = false;
        settings.mask = false;
        kVariants[v].apply(settings);
        renderers[c * n_variants + v] = std::make_unique<SensorRenderer>(
            sensor_preset(preset), std::vector{cases[c].shape}, settings);
      }
    }
    for (int r = 0; r < args.repeats; ++r) {
      for (std::size_t c = 0; c < cases.size(); ++c) {
        for (int v = 0; v < n_variants; ++v) {
          const std::size_t k = c * n_variants + v;
          ms[k].push_back(time_frames(*renderers[k], {cases[c].T_sensor_object}, frames[k], budget_s));
        }
      }
    }
    for (int v = 0; v < n_variants; ++v) {
      out << "| " << kVariants[v].name << " |";
      for (std::size_t c = 0; c < cases.size(); ++c) {
        const double m = upper_median(ms[c * n_variants + v]);
        const double base = upper_median(ms[c * n_variants]);
        char cell[64];
        std::snprintf(cell, sizeof(cell), " %.3f (%.2fx) |", m, m / base);
        out << cell;
      }
      out << "\n";
    }
    out << "\n";
    std::printf("%s", out.str().c_str());
    std::fflush(stdout);
    report += out.str();
    out.str("");
  }
  // Written once, whole: a stopped or failed run leaves an earlier report as it was.
  if (!args.markdown.empty()) write_text_atomically(args.markdown, report);
  return 0;
}

}  // namespace

int run_bench(const BenchArgs& in) {
  BenchArgs args = in;
  if (args.quick) {
    args.frames = std::min(args.frames, 200);
    args.repeats = std::min(args.repeats, 3);
  }
  std::unique_ptr<tbb::global_control> limit;
  if (args.threads > 0) {
    limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                  args.threads);
  }
  const int threads = int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
  // A path that cannot be written fails now, not after the whole benchmark.
  if (!args.markdown.empty()) {
    check_output_file(args.markdown, {FileKind::kText}, "--markdown");
    check_can_write(args.markdown);
  }
  const std::vector<Case> cases = bench_cases();
  if (args.ablation) return run_ablation(cases, args);
  std::ostringstream head, table;
  head << "Command: `" << command(args) << "`  \n"
       << machine_line() << "  \n"
       << "Date: " << utc_now() << "  \n"
       << "Colour + normals, noise on; frames/s with " << threads
       << " threads rendering frames in parallel, ms/frame with one thread alone; median of "
       << args.repeats << " runs of " << args.frames
       << " frames, the runs of the four cases of a row group interleaved.\n\n";
  table << "| case | resolution | shadows | frames/s (" << threads
        << " threads) | ms/frame (1 thread) | contact px | rays/frame | triangles/frame |\n"
        << "|---|---|---|---:|---:|---:|---:|---:|\n";
  std::printf("%s%s", head.str().c_str(), table.str().c_str());
  std::fflush(stdout);
  for (const char* preset : {"digit", "digit_240x320"}) {
    for (bool shadows : {false, true}) {
      const std::vector<Timing> timings = time_cases(cases, preset, shadows, args);
      const auto cam = sensor_preset(preset).camera;
      for (std::size_t c = 0; c < cases.size(); ++c) {
        const Timing& t = timings[c];
        char row[512];
        std::snprintf(row, sizeof(row), "| %s | %dx%d | %s | %.0f | %.3f | %.0f | %.0f | %.0f |\n",
                      cases[c].name.c_str(), cam.width, cam.height, shadows ? "on" : "off",
                      t.fps, t.ms_one_thread, t.contact_pixels, t.rays, t.triangles);
        table << row;
        std::printf("%s", row);
        std::fflush(stdout);
      }
    }
  }
  if (!args.markdown.empty()) {
    write_text_atomically(args.markdown, head.str() + table.str());
  }
  return 0;
}

}  // namespace pg
