#include "bench.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <sstream>

#include "pg/sim/primitives.h"
#include "pg/sim/renderer.h"

namespace pg {
namespace {

struct Case {
  std::string name;
  std::shared_ptr<const ObjectShape> shape;
  SE3 T_sensor_object;
};

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Timing {
  double fps = 0;
  double contact_pixels = 0;
  double rays = 0;
};

Timing time_case(const Case& c, const std::string& preset, bool shadows, const BenchArgs& args) {
  RenderSettings settings;
  settings.depth = false;
  settings.mask = false;
  settings.shadows = shadows;
  const SensorRenderer renderer(sensor_preset(preset), {c.shape}, settings);
  const std::vector<SE3> poses = {c.T_sensor_object};
  const RenderedFrame probe = renderer.render(poses, 0);
  Timing t;
  t.contact_pixels = probe.stats.contact_pixels;
  t.rays = double(probe.stats.rays_cast);
  std::vector<double> fps;
  for (int r = 0; r < args.repeats; ++r) {
    const auto start = std::chrono::steady_clock::now();
    tbb::parallel_for(0, args.frames, [&](int f) { renderer.render(poses, std::uint64_t(f)); });
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    fps.push_back(args.frames / s);
  }
  t.fps = median(fps);
  return t;
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
  const auto sphere = std::make_shared<ObjectShape>(make_uv_sphere(0.006f, 72, 144));     // ~20k tris
  const auto dense = std::make_shared<ObjectShape>(make_uv_sphere(0.006f, 250, 400));     // 200k tris
  const auto slab = std::make_shared<ObjectShape>(make_box({0.015f, 0.015f, 0.005f}));
  const std::vector<Case> cases = {
      {"(a) no contact: sphere r 6 mm, 5 mm above the gel", sphere, SE3::Translation({0, 0, 0.011})},
      {"(b) sphere r 6 mm pressed 1 mm", sphere, SE3::Translation({0, 0, 0.005})},
      {"(c) flat face pressed 1.5 mm (half the gel)", slab, SE3::Translation({0, 0, 0.0035})},
      {"(d) 200k-triangle sphere pressed 1 mm", dense, SE3::Translation({0, 0, 0.005})},
  };
  std::ostringstream table;
  table << "| case | resolution | shadows | frames/s | contact px | rays/frame |\n"
        << "|---|---|---|---:|---:|---:|\n";
  std::printf("tacsim bench: colour + normals, noise on, %d threads, median of %d runs of %d frames\n",
              threads, args.repeats, args.frames);
  for (const char* preset : {"digit", "digit_240x320"}) {
    for (bool shadows : {false, true}) {
      for (const auto& c : cases) {
        const Timing t = time_case(c, preset, shadows, args);
        const auto cam = sensor_preset(preset).camera;
        char row[512];
        std::snprintf(row, sizeof(row), "| %s | %dx%d | %s | %.0f | %.0f | %.0f |\n", c.name.c_str(),
                      cam.width, cam.height, shadows ? "on" : "off", t.fps, t.contact_pixels, t.rays);
        table << row;
        std::printf("%s", row);
        std::fflush(stdout);
      }
    }
  }
  if (!args.markdown.empty()) {
    std::ofstream out(args.markdown);
    out << table.str();
    if (!out) {
      std::fprintf(stderr, "error: %s: cannot write\n", args.markdown.c_str());
      return 1;
    }
  }
  return 0;
}

}  // namespace pg
