// Speed of the tracker's measurement front end (issue 4 targets, Release, 2 cores):
//   normals -> cloud     120x160 < 0.3 ms, 240x320 < 1 ms per frame
//   ICP                  5k points against a 50k-point patch, 10 iterations, tree reused: < 1 ms
//   Poisson              cropped vs full-image integration of a small contact
//   back-projection      contact pixels -> points with normals in S
//   graph update         one PatchGraphTracker::add (registrations + fixed-lag solve), bench_graph
// Data are analytic (a sphere pressed into the DIGIT gel; a smooth bumpy patch), so the benchmark
// needs neither the renderer nor files.
//
//   bench_tracker --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>
#include <random>

#include "pg/graph/tracker.h"
#include "pg/tracker/contact_cloud.h"
#include "pg/tracker/icp.h"

namespace pg {
namespace {

// Normals of a sphere (radius R, centre c in S) pressed into the rigid gel; elsewhere the
// undeformed gel's normals.
ImageF sphere_normals(const GelRays& rays, const ImageF& reference, const Eigen::Vector3d& c,
                      double R) {
  ImageF n = reference;
  const ImageF u = sphere_indentation(rays, c, R);
  for (int i = 0; i < rays.width * rays.height; ++i) {
    if (u.data[std::size_t(i)] <= 0.0f) continue;
    const Eigen::Vector3d normal =
        (c - rays.point(i, u.data[std::size_t(i)]).cast<double>()).normalized();
    for (int k = 0; k < 3; ++k) n.data[3 * std::size_t(i) + k] = float(normal[k]);
  }
  return n;
}

struct SphereFrame {
  SensorModel sensor;
  ImageF normals;
};

SphereFrame sphere_frame(const char* preset, double R, double press) {
  SphereFrame f;
  f.sensor = sensor_preset(preset);
  const GelRays rays = make_gel_rays(f.sensor.camera, f.sensor.gel);
  f.normals = sphere_normals(rays, undeformed_gel_normals(rays), {0.001, -0.002, R - press}, R);
  return f;
}

// Normals -> indentation -> mask -> cloud for one frame (a 6 mm sphere pressed 1 mm).
void BM_NormalsToCloud(benchmark::State& state, const char* preset) {
  const SphereFrame f = sphere_frame(preset, 0.006, 0.001);
  ContactCloudBuilder builder(f.sensor, ContactCloudOptions());
  ContactFrame frame;
  builder.build(f.normals, frame);  // plans made here, as on a tracker's first frame
  for (auto _ : state) {
    builder.build(f.normals, frame);
    benchmark::DoNotOptimize(frame.cloud_sensor.points.data());
  }
  state.counters["points"] = double(frame.cloud_sensor.size());
  state.counters["grid_px"] = double(frame.depth.window.area());
}
BENCHMARK_CAPTURE(BM_NormalsToCloud, digit_120x160, "digit")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_NormalsToCloud, digit_240x320, "digit_240x320")
    ->Unit(benchmark::kMicrosecond);

// Integration alone on a small contact (a 4 mm sphere pressed 0.3 mm at 240x320), cropped to the
// contact or over the whole image, by the parity (default) or the averaged integration.
void BM_PoissonSmallContact(benchmark::State& state, bool crop, DepthIntegration integration) {
  const SphereFrame f = sphere_frame("digit_240x320", 0.004, 0.0003);
  DepthOptions options;
  options.crop = crop;
  options.integration = integration;
  DepthFromNormals depth(f.sensor, options);
  DepthResult out;
  depth.compute(f.normals, out);
  for (auto _ : state) {
    depth.compute(f.normals, out);
    benchmark::DoNotOptimize(out.depth.data.data());
  }
  state.counters["grid_px"] = double(out.window.area());
}
BENCHMARK_CAPTURE(BM_PoissonSmallContact, cropped, true, DepthIntegration::kParity)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_PoissonSmallContact, cropped_averaged, true, DepthIntegration::kAveraged)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_PoissonSmallContact, full_image, false, DepthIntegration::kParity)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_PoissonSmallContact, full_image_averaged, false, DepthIntegration::kAveraged)
    ->Unit(benchmark::kMicrosecond);

// Back-projection alone: the contact pixels of a 6 mm sphere pressed 1 mm, into points with
// normals in S (the cloud the registrations align).
void BM_BackProjection(benchmark::State& state, const char* preset) {
  const SphereFrame f = sphere_frame(preset, 0.006, 0.001);
  ContactCloudBuilder builder(f.sensor, ContactCloudOptions());
  const ContactFrame frame = builder.build(f.normals);
  PointCloud cloud;
  for (auto _ : state) {
    back_project_contact(builder.rays(), frame.depth.depth, frame.mask.mask, frame.mask.box,
                         f.normals, cloud);
    benchmark::DoNotOptimize(cloud.points.data());
  }
  state.counters["points"] = double(cloud.size());
}
BENCHMARK_CAPTURE(BM_BackProjection, digit_120x160, "digit")->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(BM_BackProjection, digit_240x320, "digit_240x320")
    ->Unit(benchmark::kMicrosecond);

// A smooth bumpy surface z = A sin(x / l) sin(y / l) with its normals: fully constrained.
Eigen::Vector3f bumpy_point(float x, float y) {
  const float A = 0.0005f, l = 0.0015f;
  return {x, y, A * std::sin(x / l) * std::sin(y / l)};
}
Eigen::Vector3f bumpy_normal(float x, float y) {
  const float A = 0.0005f, l = 0.0015f;
  const float zx = A / l * std::cos(x / l) * std::sin(y / l);
  const float zy = A / l * std::sin(x / l) * std::cos(y / l);
  return Eigen::Vector3f(-zx, -zy, 1.0f).normalized();
}

// 0.24 mm and 1.6 deg; 30 um and 0.3 deg.
const SE3 kLargeMotion = SE3::exp((Vector6d() << 2e-4, -1e-4, 1e-4, 0.01, -0.015, 0.02).finished());
const SE3 kSmallMotion = SE3::exp((Vector6d() << 2e-5, -1.5e-5, 1.5e-5, 0.003, -0.003, 0.003).finished());

struct IcpData {
  // 5k points over 5 x 5 mm, moved by `motion`: a jittered 71 x 71 grid in raster order, as
  // back-projected contact pixels come.
  PointCloud source;
  std::unique_ptr<PointCloudTree> patch;  // 50k points over 10 x 10 mm, on a grid
};

IcpData icp_data(const SE3& motion, bool voxel_grid = true) {
  IcpData d;
  PointCloud patch;
  const int side = 224;  // 50176 points, 0.045 mm apart
  for (int a = 0; a < side; ++a) {
    for (int b = 0; b < side; ++b) {
      const float x = -0.005f + 0.01f * a / (side - 1), y = -0.005f + 0.01f * b / (side - 1);
      patch.push_back(bumpy_point(x, y), bumpy_normal(x, y));
    }
  }
  d.patch = std::make_unique<PointCloudTree>(std::move(patch), 12, voxel_grid);
  std::mt19937 rng(1);
  std::uniform_real_distribution<float> jitter(-0.02e-3f, 0.02e-3f);
  const Eigen::Matrix3f R = motion.rotation_matrix().cast<float>();
  const Eigen::Vector3f t = motion.translation().cast<float>();
  for (int a = 0; a < 71; ++a) {
    for (int b = 0; b < 71; ++b) {
      const float x = -0.0025f + 0.005f * b / 70 + jitter(rng);
      const float y = -0.0025f + 0.005f * a / 70 + jitter(rng);
      d.source.push_back(R * bumpy_point(x, y) + t, R * bumpy_normal(x, y));
    }
  }
  return d;
}

// 10 Gauss-Newton iterations (convergence disabled), the patch tree built once outside the loop.
// Arguments: oneTBB threads (1 shows the work itself: CPU time = wall time); 1 = voxel grid + k-d
// tree (the default), 0 = k-d tree alone.
void BM_Icp5kAgainst50k(benchmark::State& state) {
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    std::size_t(state.range(0)));
  const IcpData d = icp_data(kLargeMotion, state.range(1) != 0);
  IcpOptions options;
  options.max_iterations = 10;
  options.convergence_translation_m = 0;
  options.convergence_rotation_rad = 0;
  PointToPlaneIcp icp(options);
  IcpResult r;
  for (auto _ : state) {
    r = icp.align(d.source, *d.patch, SE3::Identity());
    benchmark::DoNotOptimize(r.T_target_source);
  }
  state.counters["iterations"] = r.iterations;
  state.counters["coarse"] = r.coarse_iterations;
  state.counters["queries"] = double(icp.last_queries());
  state.counters["inliers"] = r.inliers;
}
BENCHMARK(BM_Icp5kAgainst50k)
    ->ArgsProduct({{1, 2}, {1, 0}})
    ->ArgNames({"threads", "grid"})
    ->Unit(benchmark::kMicrosecond)->UseRealTime();

// The same with a 0.1 mm voxel grid on the source (about 2.5k points left).
void BM_Icp5kVoxel100umAgainst50k(benchmark::State& state) {
  const tbb::global_control threads(tbb::global_control::max_allowed_parallelism,
                                    std::size_t(state.range(0)));
  const IcpData d = icp_data(kLargeMotion);
  IcpOptions options;
  options.max_iterations = 10;
  options.convergence_translation_m = 0;
  options.convergence_rotation_rad = 0;
  options.voxel_size_m = 1e-4;
  PointToPlaneIcp icp(options);
  IcpResult r;
  for (auto _ : state) {
    r = icp.align(d.source, *d.patch, SE3::Identity());
    benchmark::DoNotOptimize(r.T_target_source);
  }
  state.counters["source_points"] = r.source_points;
  state.counters["queries"] = double(icp.last_queries());
}
BENCHMARK(BM_Icp5kVoxel100umAgainst50k)->Arg(1)->Arg(2)->Unit(benchmark::kMicrosecond)->UseRealTime();

// A frame-to-frame case: the guess is 30 um and 0.3 deg off (motion between frames at 60 Hz),
// default convergence thresholds.
void BM_Icp5kAgainst50kConverging(benchmark::State& state) {
  const IcpData d = icp_data(kSmallMotion);
  PointToPlaneIcp icp;
  IcpResult r;
  for (auto _ : state) {
    r = icp.align(d.source, *d.patch, SE3::Identity());
    benchmark::DoNotOptimize(r.T_target_source);
  }
  state.counters["iterations"] = r.iterations;
  state.counters["coarse"] = r.coarse_iterations;
  state.counters["queries"] = double(icp.last_queries());
}
BENCHMARK(BM_Icp5kAgainst50kConverging)->Unit(benchmark::kMicrosecond)->UseRealTime();

// Building the 50k-point patch tree (paid once per patch update, not per frame). Argument: 1 =
// with the voxel grid, 0 = k-d tree alone.
void BM_BuildTree50k(benchmark::State& state) {
  const IcpData d = icp_data(kLargeMotion);
  for (auto _ : state) {
    PointCloudTree tree(d.patch->cloud(), 12, state.range(0) != 0);
    benchmark::DoNotOptimize(&tree);
  }
}
BENCHMARK(BM_BuildTree50k)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond);

// One graph update (PatchGraphTracker::add: image-to-image and image-to-patch ICP, the fixed-lag
// Levenberg-Marquardt solve, key frames) on a contact that rocks periodically: the bumpy patch
// (3k points over 4 x 4 mm) seen through a sensor at rest while the object rotates +-3 deg and
// slides +-0.3 mm with a period of 120 frames. The tracker has seen 60 frames before timing, so
// its window and patch are full. Argument: the method (0 constvel, 1 imagetoimage, 2 patchgraph).
void BM_GraphUpdate(benchmark::State& state) {
  constexpr int kPeriod = 120;
  PointCloud surface_object;
  for (int a = 0; a < 55; ++a) {
    for (int b = 0; b < 55; ++b) {
      const float x = -0.002f + 0.004f * a / 54, y = -0.002f + 0.004f * b / 54;
      surface_object.push_back(bumpy_point(x, y), bumpy_normal(x, y));
    }
  }
  std::vector<TrackerInput> inputs(kPeriod);
  for (int f = 0; f < kPeriod; ++f) {
    const double phase = 2 * kPi * f / kPeriod;
    const SE3 T_world_object = SE3::exp(
        (Vector6d() << 3e-4 * std::sin(phase), 0, 0, 0.05 * std::sin(phase), 0.03 * std::cos(phase), 0)
            .finished());
    TrackerInput& in = inputs[f];
    in.T_world_sensor_measured = SE3();
    in.T_world_object_prior = T_world_object;
    const Eigen::Matrix3f R = T_world_object.rotation_matrix().cast<float>();
    const Eigen::Vector3f t = T_world_object.translation().cast<float>();
    for (std::size_t i = 0; i < surface_object.size(); ++i) {
      in.cloud_sensor.push_back(R * surface_object.points[i] + t, R * surface_object.normals[i]);
    }
  }
  GraphOptions options;
  options.method = static_cast<Method>(state.range(0));
  PatchGraphTracker tracker(options);
  int frame = 0;
  for (; frame < 60; ++frame) tracker.add(inputs[frame % kPeriod]);
  for (auto _ : state) {
    const TrackerEstimate est = tracker.add(inputs[frame++ % kPeriod]);
    benchmark::DoNotOptimize(est.T_world_object);
  }
  state.counters["points"] = double(surface_object.size());
}
BENCHMARK(BM_GraphUpdate)->Arg(0)->Arg(1)->Arg(2)->ArgName("method")
    ->Unit(benchmark::kMicrosecond)->UseRealTime();

}  // namespace
}  // namespace pg

BENCHMARK_MAIN();
