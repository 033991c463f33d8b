// Speed of the renderer's kernels, one at a time (the whole frame is timed by `tacsim bench`):
//   ray casting     16-ray packets against a 20k-triangle sphere's BVH, rays limited to the slab
//   gel model       the elastic closing + smoothing of a sphere's rigid indentation
//   normals         the deformed surface's normals over the moved pixels
//   shading         three lights, Blinn-Phong, over the moved pixels
//   noise           fresh Gaussian noise over every pixel of a colour frame
// Data: a 6 mm sphere pressed 1 mm into the DIGIT gel at 240x320, its rigid indentation
// computed analytically per pixel, so each kernel sees what it sees inside a frame.
//
//   bench_sim --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <cmath>
#include <memory>

#include "gel_surface.h"
#include "pg/sim/primitives.h"
#include "pg/sim/renderer.h"
#include "raycast.h"
#include "shading.h"

namespace pg {
namespace {

constexpr float kRadius = 0.006f, kPress = 0.001f;

// The sphere's centre in S: its lowest point kPress below the gel centre.
Eigen::Vector3f sphere_centre() { return {0, 0, kRadius - kPress}; }

struct Contact {
  SensorModel sensor = sensor_preset("digit_240x320");
  GelGeometry gel = make_gel_geometry(sensor);
  std::vector<float> rigid;  // rigid indentation per pixel [m]
  PixelRect rect;            // its bounding box
  float deepest = 0;

  Contact() {
    rigid.assign(std::size_t(gel.width) * gel.height, 0.0f);
    rect = {gel.width, gel.height, 0, 0};
    const Eigen::Vector3f c = sphere_centre();
    for (int y = 0; y < gel.height; ++y) {
      for (int x = 0; x < gel.width; ++x) {
        const int i = gel.index(x, y);
        // First hit of origin + d t with the sphere; indentation where it is in front of the gel.
        const Eigen::Vector3f d = gel.dir_sensor[i], oc = gel.origin_sensor - c;
        const float a = d.squaredNorm(), b = 2 * d.dot(oc),
                    cc = oc.squaredNorm() - kRadius * kRadius;
        const float disc = b * b - 4 * a * cc;
        if (disc <= 0) continue;
        const float t = (-b - std::sqrt(disc)) / (2 * a);
        const float r = gel.t_gel[i] - t;
        if (r <= 0) continue;
        rigid[i] = std::min(r, float(sensor.gel.max_indentation_m));
        deepest = std::max(deepest, rigid[i]);
        rect.include(x, y);
      }
    }
  }
};

const Contact& contact() {
  static const Contact c;
  return c;
}

// Rays through the contact's pixels, 16 at a time, each limited to the gel slab.
void BM_RayCastPackets(benchmark::State& state) {
  const Contact& c = contact();
  const ObjectShape shape(make_uv_sphere(kRadius, 72, 144));
  const SE3 T_sensor_object = SE3::Translation(sphere_centre().cast<double>());
  std::vector<RayPacket> packets;
  RayPacket p;
  p.origin_sensor = c.gel.origin_sensor;
  const float slab = float(c.sensor.gel.max_indentation_m);
  for (int y = c.rect.y0; y < c.rect.y1; ++y) {
    for (int x = c.rect.x0; x < c.rect.x1; ++x) {
      const int i = c.gel.index(x, y);
      p.dir_sensor[p.count] = c.gel.dir_sensor[i];
      p.tnear[p.count] = c.gel.t_gel[i] - slab;
      p.tfar[p.count] = p.tfar_open[p.count] = c.gel.t_gel[i];
      if (++p.count == kPacket) {
        packets.push_back(p);
        p.count = 0;
      }
    }
  }
  PacketHits hits;
  for (auto _ : state) {
    for (const RayPacket& packet : packets) {
      intersect(shape, T_sensor_object, packet, hits);
      benchmark::DoNotOptimize(hits.t[0]);
    }
  }
  state.counters["rays"] = double(packets.size() * kPacket);
  state.SetItemsProcessed(state.iterations() * long(packets.size()) * kPacket);
}
BENCHMARK(BM_RayCastPackets)->Unit(benchmark::kMicrosecond);

// The elastic closing and smoothing of the rigid indentation (rho 0.5 mm, the DIGIT default).
void BM_ElasticGel(benchmark::State& state) {
  const Contact& c = contact();
  const ElasticKernel kernel = make_elastic_kernel(c.sensor.gel.elastic, c.gel.px_per_m,
                                                   std::max(c.gel.width, c.gel.height));
  const std::size_t n = c.rigid.size();
  std::vector<float> a(n, 0.0f), b(n, 0.0f), u(n, 0.0f);
  PixelRect deformed;
  for (auto _ : state) {
    deformed = elastic_displacement(kernel, c.gel.width, c.gel.height, c.rect, c.deepest,
                                    c.rigid.data(), a.data(), b.data(), u.data());
    benchmark::DoNotOptimize(u.data());
  }
  state.counters["contact_px"] = double(c.rect.area());
  state.counters["deformed_px"] = double(deformed.area());
}
BENCHMARK(BM_ElasticGel)->Unit(benchmark::kMicrosecond);

// Normals of the surface displaced by the rigid indentation, over its rectangle plus a pixel.
void BM_SurfaceNormals(benchmark::State& state) {
  const Contact& c = contact();
  std::vector<float> normals(c.rigid.size() * 3, 0.0f);
  const PixelRect rect = c.rect.dilated(1).clipped(c.gel.width, c.gel.height);
  for (auto _ : state) {
    surface_normals(c.gel, c.rigid.data(), rect, normals.data());
    benchmark::DoNotOptimize(normals.data());
  }
  state.counters["px"] = double(rect.area());
}
BENCHMARK(BM_SurfaceNormals)->Unit(benchmark::kMicrosecond);

// Three-light Blinn-Phong over the contact's pixels (no shadows).
void BM_Shading(benchmark::State& state) {
  const Contact& c = contact();
  const Shader shader = make_shader(c.sensor);
  std::vector<float> normals(c.rigid.size() * 3, 0.0f);
  surface_normals(c.gel, c.rigid.data(), c.rect, normals.data());
  const int n = int(c.rect.area());
  std::vector<float> px, py, pz, nx, ny, nz;
  for (int y = c.rect.y0; y < c.rect.y1; ++y) {
    for (int x = c.rect.x0; x < c.rect.x1; ++x) {
      const int i = c.gel.index(x, y);
      const Eigen::Vector3f p = c.gel.point(i, c.rigid[i]);
      px.push_back(p.x()), py.push_back(p.y()), pz.push_back(p.z());
      nx.push_back(normals[3 * i]), ny.push_back(normals[3 * i + 1]),
          nz.push_back(normals[3 * i + 2]);
    }
  }
  std::vector<float> rgb(std::size_t(n) * 3);
  const ShadeSpan span{n, px.data(), py.data(), pz.data(), nx.data(), ny.data(), nz.data()};
  for (auto _ : state) {
    shade_span(shader, span, rgb.data());
    benchmark::DoNotOptimize(rgb.data());
  }
  state.SetItemsProcessed(state.iterations() * n);
}
BENCHMARK(BM_Shading)->Unit(benchmark::kMicrosecond);

// Noise over a whole 240x320 colour frame (every pixel gets fresh noise every frame).
void BM_Noise(benchmark::State& state) {
  const NoiseTable table(7.0f);
  const std::size_t n = 240 * 320 * 3;
  std::vector<std::int16_t> values(n, table.to_fixed(128.0f));
  std::vector<std::uint8_t> out(n);
  std::uint64_t seed = 0;
  for (auto _ : state) {
    table.apply(values.data(), out.data(), n, ++seed);
    benchmark::DoNotOptimize(out.data());
  }
  state.SetItemsProcessed(state.iterations() * long(n));
}
BENCHMARK(BM_Noise)->Unit(benchmark::kMicrosecond);

// The whole frame through the public API, for scale: colour + normals, noise on; shadows off
// (argument 0) or on (1).
void BM_RenderFrame(benchmark::State& state) {
  const auto shape = std::make_shared<const ObjectShape>(make_uv_sphere(kRadius, 72, 144));
  RenderSettings settings;
  settings.depth = settings.mask = false;
  settings.shadows = state.range(0) != 0;
  const SensorRenderer renderer(contact().sensor, {shape}, settings);
  const std::vector<SE3> poses = {SE3::Translation(sphere_centre().cast<double>())};
  RenderedFrame frame;
  std::uint64_t seed = 0;
  for (auto _ : state) {
    renderer.render(poses, ++seed, frame);
    benchmark::DoNotOptimize(frame.images.color.data.data());
  }
}
BENCHMARK(BM_RenderFrame)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace pg

BENCHMARK_MAIN();
