// Renderer accuracy against analytic shapes, the work-skipping paths against brute force, colour
// properties, determinism, resolution consistency and bad input.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>

#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "pg/core/image.h"
#include "pg/core/pixel_rect.h"
#include "pg/sim/mesh.h"
#include "pg/sim/mesh_sampling.h"
#include "pg/sim/normal_bound.h"
#include "pg/sim/presses.h"
#include "pg/sim/primitives.h"
#include "pg/sim/renderer.h"
#include "pg/sim/scene_renderer.h"
#include "pg/sim/shading_inversion.h"

namespace pg {
namespace {

constexpr double kRadius = 0.006;  // sphere radius [m]
constexpr double kPress = 0.001;   // press depth [m]

std::shared_ptr<const ObjectShape> sphere_shape() {
  static const auto shape = std::make_shared<ObjectShape>(make_uv_sphere(float(kRadius), 180, 360));
  return shape;
}

// A DIGIT with a flat gel, so that the analytic answers are simple.
SensorModel flat_digit(const std::string& preset = "digit_240x320", bool elastic = false) {
  SensorModel s = sensor_preset(preset);
  s.gel.sag_m = 0.0;
  s.gel.elastic.enabled = elastic;
  return s;
}

RenderSettings quiet_settings() {
  RenderSettings r;
  r.noise = false;
  return r;
}

// The sphere's centre sits kRadius - kPress above the gel plane z = 0, at (cx, cy).
SE3 pressed_sphere(double cx = 0.0, double cy = 0.0, double press = kPress) {
  return SE3::Translation({cx, cy, kRadius - press});
}

// Camera depth along pixel (x, y)'s ray of its first intersection with the analytic sphere.
double analytic_sphere_t(const CameraModel& cam, const Eigen::Vector3d& centre, int x, int y) {
  const Eigen::Vector3d o(0, 0, -cam.distance_m), d = cam.ray(x, y);
  const Eigen::Vector3d oc = o - centre;
  const double a = d.squaredNorm(), b = 2 * d.dot(oc), c = oc.squaredNorm() - kRadius * kRadius;
  const double disc = b * b - 4 * a * c;
  return disc < 0 ? INFINITY : (-b - std::sqrt(disc)) / (2 * a);
}

double angle_deg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / kPi;
}

Eigen::Vector3d normal_at(const ImageF& n, int x, int y) {
  return {n.at(x, y, 0), n.at(x, y, 1), n.at(x, y, 2)};
}

TEST(RenderSphere, RigidIndentationNormalsAndRadiusMatchTheAnalyticCap) {
  const SensorModel sensor = flat_digit();
  const SensorRenderer r(sensor, {sphere_shape()}, quiet_settings());
  const SE3 pose = pressed_sphere();
  const RenderedFrame f = r.render({pose}, 0);
  ASSERT_TRUE(f.stats.contact);
  const auto& cam = sensor.camera;
  const Eigen::Vector3d centre = pose.translation();
  // Contact radius on the gel plane: a = sqrt(2 R d - d^2).
  const double a = std::sqrt(2 * kRadius * kPress - kPress * kPress);
  const double px_per_m = cam.fx / cam.distance_m;
  int core = 0, mask_mismatch_far_from_edge = 0;
  double max_err = 0, max_angle = 0;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const double t = analytic_sphere_t(cam, centre, x, y);
      const double depth = std::max(0.0, cam.distance_m - t);
      const Eigen::Vector3d p_gel = cam.ray(x, y) * cam.distance_m;  // on the plane z = 0
      const double r_px = p_gel.head<2>().norm() * px_per_m;
      const bool analytic_contact = depth > 0;
      const bool rendered_contact = f.images.mask.at(x, y) > 0;
      // Contact radius within one pixel: the mask only disagrees within a pixel of the edge.
      if (analytic_contact != rendered_contact && std::abs(r_px - a * px_per_m) > 1.0) {
        ++mask_mismatch_far_from_edge;
      }
      if (r_px > 0.9 * a * px_per_m) continue;  // the contact core
      ++core;
      max_err = std::max(max_err, std::abs(f.images.depth.at(x, y) - depth));
      const Eigen::Vector3d p_obj = Eigen::Vector3d(0, 0, -cam.distance_m) + cam.ray(x, y) * t;
      max_angle = std::max(max_angle, angle_deg(normal_at(f.images.normal, x, y), centre - p_obj));
    }
  }
  EXPECT_GT(core, 2000);
  EXPECT_EQ(mask_mismatch_far_from_edge, 0);
  EXPECT_LT(max_err, 0.01 * kPress) << "indentation error in the core [m]";
  EXPECT_LT(max_angle, 1.0) << "normal error in the core [deg]";
}

TEST(RenderSphere, ElasticGelConformsInsideAndFallsOffSmoothlyOutside) {
  const SE3 pose = pressed_sphere();
  const RenderedFrame rigid =
      SensorRenderer(flat_digit(), {sphere_shape()}, quiet_settings()).render({pose}, 0);
  const RenderedFrame soft =
      SensorRenderer(flat_digit("digit_240x320", true), {sphere_shape()}, quiet_settings())
          .render({pose}, 0);
  const ImageF& dr = rigid.images.depth;
  const ImageF& de = soft.images.depth;
  const int w = dr.width, h = dr.height;
  double max_core_diff = 0, max_below = 0, max_step_outside = 0, max_step_core = 0;
  int outside_deformed = 0;
  for (int y = 1; y < h - 1; ++y) {
    for (int x = 1; x < w - 1; ++x) {
      const float r = dr.at(x, y), e = de.at(x, y);
      // The gel never passes through the object: elastic >= rigid (up to the 1 um blend).
      max_below = std::max(max_below, double(r - e));
      const double step = std::max(std::abs(de.at(x + 1, y) - e), std::abs(de.at(x, y + 1) - e));
      if (r > 0.5 * kPress) {
        max_core_diff = std::max(max_core_diff, double(std::abs(e - r)));
        max_step_core = std::max(max_step_core, step);
      } else if (r == 0.0f) {
        outside_deformed += e > 1e-6f;
        max_step_outside = std::max(max_step_outside, step);
      }
    }
  }
  EXPECT_LT(max_below, 1e-6) << "elastic surface below the rigid one [m]";
  EXPECT_LT(max_core_diff, 0.01 * kPress) << "elastic differs from rigid in the core [m]";
  EXPECT_GT(outside_deformed, 500) << "no fall-off around the contact";
  // Continuity at the contact edge: no step larger than the steepest step inside the contact.
  EXPECT_LE(max_step_outside, max_step_core * 1.05);
  // Smooth normals: no pixel's normal is an outlier against its 3x3 neighbourhood mean.
  double worst = 0;
  for (int y = 2; y < h - 2; ++y) {
    for (int x = 2; x < w - 2; ++x) {
      Eigen::Vector3d mean = Eigen::Vector3d::Zero();
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if (dx || dy) mean += normal_at(soft.images.normal, x + dx, y + dy);
      worst = std::max(worst, angle_deg(normal_at(soft.images.normal, x, y), mean));
    }
  }
  EXPECT_LT(worst, 3.0) << "normal outlier against its neighbours [deg]";
}

// Two renders of the same frame agree: the same contact mask up to pixels whose centre lies on
// the contact edge, indentation within 1 um, colour within 2 levels (rounding of the two paths).
// The elastic gel's sink-in ring (indented, but outside the contact mask) in m^2, for a press of
// the sphere on a flat DIGIT of `preset` with the coating's smoothing `smoothing_m`.
double sink_in_area_m2(const std::string& preset, double smoothing_m) {
  SensorModel sensor = flat_digit(preset, true);
  sensor.gel.elastic.smoothing_m = smoothing_m;
  const RenderedFrame f =
      SensorRenderer(sensor, {sphere_shape()}, quiet_settings()).render({pressed_sphere()}, 0);
  int ring = 0;
  for (std::size_t i = 0; i < f.images.mask.data.size(); ++i) {
    ring += f.images.depth.data[i] > 1e-7f && f.images.mask.data[i] == 0.0f;
  }
  const double pixel_m = sensor.camera.distance_m / sensor.camera.fx;
  return ring * pixel_m * pixel_m;
}

// The coating's smoothing is the Gaussian its sigma says at any resolution: the sink-in ring has
// one area at 120x160 and 240x320, and grows with the sigma. (Three box passes of radius at
// least 1 had smoothed 50 um as 225 um at 120x160 and as 112 um at 240x320: a ring of 15.5 and
// 8.6 mm^2, and 50 and 200 um gave the same images.)
TEST(RenderSphere, TheElasticGelsSmoothingIsTheSameAtEveryResolution) {
  const double low = sink_in_area_m2("digit", 5e-5), high = sink_in_area_m2("digit_240x320", 5e-5);
  std::printf("sink-in ring at 50 um: %.2f mm^2 at 120x160, %.2f at 240x320\n", low * 1e6,
              high * 1e6);
  EXPECT_GT(high, 1e-6);
  EXPECT_NEAR(low / high, 1.0, 0.15);
  EXPECT_GT(sink_in_area_m2("digit", 2e-4), 1.3 * low);
}

void expect_same_frame(const RenderedFrame& a, const RenderedFrame& b, const std::string& what) {
  std::size_t mask_diff = 0;
  for (std::size_t i = 0; i < a.images.mask.data.size(); ++i)
    mask_diff += a.images.mask.data[i] != b.images.mask.data[i];
  EXPECT_LE(mask_diff, a.images.mask.data.size() / 2000) << what;
  double depth_diff = 0, color_diff = 0;
  for (std::size_t i = 0; i < a.images.depth.data.size(); ++i)
    depth_diff =
        std::max(depth_diff, double(std::abs(a.images.depth.data[i] - b.images.depth.data[i])));
  for (std::size_t i = 0; i < a.images.color.data.size(); ++i)
    color_diff =
        std::max(color_diff, std::abs(double(a.images.color.data[i]) - b.images.color.data[i]));
  EXPECT_LT(depth_diff, 1e-6) << what;
  EXPECT_LE(color_diff, 2.0) << what;
}

TEST(RenderSkip, EverySkipGivesTheSameImagesAsBruteForce) {
  const auto cube = std::make_shared<ObjectShape>(make_box({0.004f, 0.004f, 0.004f}));
  // A cube corner pressed in, and a second object far away (culled).
  const SE3 corner =
      SE3(quaternion_from_rpy({0.6, 0.5, 0.3}), Eigen::Vector3d(0.001, -0.002, 0.0052));
  for (const char* preset : {"digit", "digit_240x320"}) {
    const SensorModel sensor = sensor_preset(preset);
    for (const auto& poses :
         {std::vector<SE3>{corner, pressed_sphere(0.0, 0.0, -0.01)},
          std::vector<SE3>{SE3::Translation({0, 0, 0.01}), pressed_sphere(0.001, 0.0, 0.0012)}}) {
      RenderSettings fast = quiet_settings();
      fast.noise = true;
      const RenderedFrame a = SensorRenderer(sensor, {cube, sphere_shape()}, fast).render(poses, 5);
      ASSERT_TRUE(a.stats.contact);
      EXPECT_EQ(a.stats.objects_culled, 1);
      for (int k = 0; k < 5; ++k) {
        RenderSettings slow = fast;
        const char* names[] = {"cull", "footprint", "slab", "cache", "rasterize"};
        bool* flags[] = {&slow.cull, &slow.footprint, &slow.slab_limited_rays,
                         &slow.no_contact_cache, &slow.rasterize};
        *flags[k] = false;
        const RenderedFrame b =
            SensorRenderer(sensor, {cube, sphere_shape()}, slow).render(poses, 5);
        expect_same_frame(a, b, std::string(preset) + " without " + names[k]);
        if (k == 1) {
          EXPECT_GT(b.stats.rays_cast, 3 * a.stats.rays_cast);
        }
      }
    }
  }
}

TEST(RenderSkip, RasterizationAgreesWithRaysOnThePapersObjects) {
  for (const char* name : {"toy_brick", "toy_human", "cube"}) {
    const auto shape = std::make_shared<ObjectShape>(
        load_mesh(std::string(PG_SOURCE_DIR) + "/meshes/" + name + ".glb"));
    // The object turned about z, its bottom 0.8 mm into the gel.
    const SE3 R(quaternion_from_rpy({0.0, 0.0, 0.3}), Eigen::Vector3d::Zero());
    double lowest = INFINITY;
    for (const auto& v : shape->mesh().vertices)
      lowest = std::min(lowest, (R * v.cast<double>()).z());
    const SE3 pose = SE3::Translation({0.0005, -0.001, -lowest - 0.0008}) * R;
    RenderSettings rs = quiet_settings();
    const RenderedFrame a =
        SensorRenderer(sensor_preset("digit_240x320"), {shape}, rs).render({pose}, 1);
    rs.rasterize = false;
    const RenderedFrame r =
        SensorRenderer(sensor_preset("digit_240x320"), {shape}, rs).render({pose}, 1);
    ASSERT_TRUE(a.stats.contact) << name;
    EXPECT_GT(a.stats.triangles_rasterized, 0) << name;
    EXPECT_EQ(r.stats.triangles_rasterized, 0) << name;
    expect_same_frame(a, r, name);
  }
}

// Where a pixel's ray grazed the outline of a closed mesh, the rasterizer could meet a face
// turned away from the camera first, take the ray to start inside the object and clamp the pixel
// at the gel's full 2 mm. A box pressed less than that, at seeded poses: nothing is clamped, and
// the rasterized frames agree with the ray-cast ones on the contact and its deepest point (the
// two may differ on pixels whose ray grazes the box's side, an edge of the contact).
TEST(RenderSkip, GrazingRaysDoNotStartInsideAClosedMesh) {
  const auto box = std::make_shared<ObjectShape>(make_box({0.004f, 0.004f, 0.004f}));
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const auto deepest = [](const RenderedFrame& f) {
    return *std::max_element(f.images.depth.data.begin(), f.images.depth.data.end());
  };
  for (const char* preset : {"digit", "digit_240x320"}) {
    RenderSettings rs = quiet_settings();
    const SensorRenderer raster(sensor_preset(preset), {box}, rs);
    rs.rasterize = false;
    const SensorRenderer rays(sensor_preset(preset), {box}, rs);
    int rasterized = 0;
    for (int k = 0; k < 40; ++k) {
      const SE3 R(quaternion_from_rpy({3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng)}),
                  Eigen::Vector3d::Zero());
      double lowest = INFINITY;
      for (const auto& v : box->mesh().vertices)
        lowest = std::min(lowest, (R * v.cast<double>()).z());
      const double press = 0.001 + 0.0009 * u(rng);  // 0.1 to 1.9 mm
      const SE3 pose = SE3::Translation({0.004 * u(rng), 0.006 * u(rng), -lowest - press}) * R;
      const RenderedFrame a = raster.render({pose}, 0), b = rays.render({pose}, 0);
      const std::string what = std::string(preset) + " pose " + std::to_string(k);
      rasterized += a.stats.triangles_rasterized > 0;
      EXPECT_EQ(a.stats.clamped_pixels, 0) << what;
      EXPECT_EQ(b.stats.clamped_pixels, 0) << what;
      EXPECT_NEAR(deepest(a), deepest(b), 1e-6) << what;
      std::size_t mask_diff = 0;
      for (std::size_t i = 0; i < a.images.mask.data.size(); ++i)
        mask_diff += a.images.mask.data[i] != b.images.mask.data[i];
      EXPECT_LE(mask_diff, a.images.mask.data.size() / 2000) << what;
    }
    EXPECT_GT(rasterized, 30) << preset;
  }
}

TEST(RenderColor, NoContactFrameIsTheBackgroundAndFlatPressKeepsIt) {
  SensorModel sensor = flat_digit("digit", false);
  const auto slab = std::make_shared<ObjectShape>(make_box({0.02f, 0.02f, 0.005f}));
  const SensorRenderer r(sensor, {slab}, quiet_settings());
  const RenderedFrame none = r.render({SE3::Translation({0, 0, 0.01})}, 0);
  EXPECT_FALSE(none.stats.contact);
  ImageU8 bg(r.background_color().width, r.background_color().height, 3);
  for (std::size_t i = 0; i < bg.data.size(); ++i) {
    bg.data[i] = std::uint8_t(std::clamp(r.background_color().data[i], 0.0f, 1.0f) * 255.0f + 0.5f);
  }
  EXPECT_EQ(none.images.color.data, bg.data);
  // A flat face 0.3 mm into a flat gel: the core keeps the background's colour.
  const RenderedFrame flat = r.render({SE3::Translation({0, 0, 0.005 - 0.0003})}, 0);
  ASSERT_TRUE(flat.stats.contact);
  int checked = 0;
  for (int y = 40; y < 120; ++y) {
    for (int x = 30; x < 90; ++x) {
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(flat.images.color.at(x, y, c), bg.at(x, y, c), 3);
      ++checked;
    }
  }
  EXPECT_EQ(checked, 80 * 60);
}

TEST(RenderColor, SlopeTowardALightBrightensItsChannel) {
  const SensorModel sensor = flat_digit("digit_240x320", false);
  const SensorRenderer r(sensor, {sphere_shape()}, quiet_settings());
  const RenderedFrame f = r.render({pressed_sphere()}, 0);
  const auto& cam = sensor.camera;
  for (std::size_t k = 0; k < sensor.lights.size(); ++k) {
    const int c = sensor.lights[k].color.maxCoeff() == sensor.lights[k].color.x() ? 0
                  : sensor.lights[k].color.y() > 0.5                              ? 1
                                                                                  : 2;
    const Eigen::Vector2d dir = sensor.lights[k].position_m.head<2>().normalized();
    // Points 2 mm from the contact centre, toward and away from the light.
    const Eigen::Vector2d toward =
        Eigen::Vector2d(cam.cx, cam.cy) + dir * 0.002 * cam.fx / cam.distance_m;
    const Eigen::Vector2d away =
        Eigen::Vector2d(cam.cx, cam.cy) - dir * 0.002 * cam.fx / cam.distance_m;
    const int tx = int(std::lround(toward.x())), ty = int(std::lround(toward.y()));
    const int ax = int(std::lround(away.x())), ay = int(std::lround(away.y()));
    const double bg_t = r.background_color().at(tx, ty, c) * 255.0;
    const double bg_a = r.background_color().at(ax, ay, c) * 255.0;
    EXPECT_GT(f.images.color.at(tx, ty, c), bg_t + 5) << "light " << k;
    EXPECT_LT(f.images.color.at(ax, ay, c), bg_a - 5) << "light " << k;
  }
}

TEST(RenderColor, DeterministicWithASeedAndNoiseHasTheConfiguredSigma) {
  const SensorModel sensor = sensor_preset("digit");
  RenderSettings s;  // noise on
  const SensorRenderer r(sensor, {sphere_shape()}, s);
  const RenderedFrame a = r.render({pressed_sphere()}, 42), b = r.render({pressed_sphere()}, 42);
  const RenderedFrame c = r.render({pressed_sphere()}, 43);
  EXPECT_EQ(a.images.color.data, b.images.color.data);
  EXPECT_NE(a.images.color.data, c.images.color.data);
  // Noise statistics on a no-contact frame, where the clean image is the background.
  const RenderedFrame n = r.render({pressed_sphere(0, 0, -0.01)}, 7);
  double sum = 0, sum_sq = 0;
  int count = 0;
  for (std::size_t i = 0; i < n.images.color.data.size(); ++i) {
    const double clean = r.background_color().data[i] * 255.0;
    if (clean < 30 || clean > 225) continue;  // away from clipping
    const double e = n.images.color.data[i] - clean;
    sum += e;
    sum_sq += e * e;
    ++count;
  }
  ASSERT_GT(count, 10000);
  EXPECT_NEAR(sum / count, 0.0, 0.3);
  EXPECT_NEAR(std::sqrt(sum_sq / count), std::sqrt(7.0 * 7.0 + 1.0 / 12.0), 0.3);
}

TEST(RenderResolution, HalfResolutionAgreesWithDownsampledFullResolution) {
  const SE3 pose =
      SE3(quaternion_from_rpy({0.1, 0.0, 0.0}), Eigen::Vector3d(0.001, 0.0015, kRadius - kPress));
  const RenderedFrame lo =
      SensorRenderer(sensor_preset("digit"), {sphere_shape()}, quiet_settings()).render({pose}, 0);
  const RenderedFrame hi =
      SensorRenderer(sensor_preset("digit_240x320"), {sphere_shape()}, quiet_settings())
          .render({pose}, 0);
  double color_err = 0, depth_err = 0;
  for (int y = 0; y < 160; ++y) {
    for (int x = 0; x < 120; ++x) {
      for (int c = 0; c < 3; ++c) {
        double v = 0;
        for (int k = 0; k < 4; ++k) v += hi.images.color.at(2 * x + (k & 1), 2 * y + (k >> 1), c);
        color_err += std::abs(v / 4 - lo.images.color.at(x, y, c));
      }
      double d = 0;
      for (int k = 0; k < 4; ++k) d += hi.images.depth.at(2 * x + (k & 1), 2 * y + (k >> 1));
      depth_err = std::max(depth_err, std::abs(d / 4 - lo.images.depth.at(x, y)));
    }
  }
  EXPECT_LT(color_err / (120 * 160 * 3), 1.0) << "mean colour difference [levels]";
  EXPECT_LT(depth_err, 0.1 * kPress) << "largest depth difference [m]";
}

// A sensor of a few pixels, or one with a field of view near 180 degrees, has so few pixels per
// metre of gel that a tile's margin was centimetres: the rays then started behind the camera
// (Embree aborts on that).
TEST(RenderResolution, TinyImagesAndWideFieldsOfViewRender) {
  for (const int size : {8, 10, 11}) {
    SensorModel s = flat_digit("digit");
    s.camera = s.camera.resized(size, size);
    const RenderedFrame f =
        SensorRenderer(s, {sphere_shape()}, quiet_settings()).render({pressed_sphere()}, 0);
    float deepest = 0;
    for (float d : f.images.depth.data) deepest = std::max(deepest, d);
    // The pixel centres (2-3 mm apart) miss the press's deepest point by up to a millimetre.
    EXPECT_GT(deepest, 0.5 * kPress) << size << "x" << size;
    EXPECT_LT(deepest, 1.01 * kPress) << size << "x" << size;
  }
  SensorModel wide = flat_digit("digit");
  wide.camera =
      CameraModel::from_vertical_fov(120, 160, 3.1, wide.camera.distance_m, wide.camera.near_m);
  const RenderedFrame f =
      SensorRenderer(wide, {sphere_shape()}, quiet_settings()).render({pressed_sphere()}, 0);
  for (float d : f.images.depth.data) ASSERT_TRUE(std::isfinite(d));
}

TEST(RenderBadInput, OpenMeshRendersWhereItCrossesTheGel) {
  // A single open square sheet, tilted, crossing the gel surface.
  TriangleMesh sheet;
  sheet.vertices = {
      {-0.005f, -0.005f, 0}, {0.005f, -0.005f, 0}, {0.005f, 0.005f, 0}, {-0.005f, 0.005f, 0}};
  sheet.triangles = {{0, 1, 2}, {0, 2, 3}};
  const auto shape = std::make_shared<ObjectShape>(sheet);
  EXPECT_FALSE(shape->closed());
  const SensorRenderer r(flat_digit("digit"), {shape}, quiet_settings());
  const RenderedFrame f =
      r.render({SE3(quaternion_from_rpy({0, 0.1, 0}), Eigen::Vector3d::Zero())}, 0);
  ASSERT_TRUE(f.stats.contact);
  // Contact on one side of the tilt only, never deeper than the sheet goes.
  int left = 0, right = 0;
  for (int y = 0; y < 160; ++y)
    for (int x = 0; x < 120; ++x)
      if (f.images.mask.at(x, y)) (x < 60 ? left : right)++;
  EXPECT_GT(left + right, 100);
  EXPECT_TRUE(left == 0 || right == 0) << left << " " << right;
}

// A press twice as deep as the gel allows: the indentation is clamped, and the contact points
// are the object's surface only where a ray meets it (where the ray starts inside the sphere,
// past the gel's base, there is none; they were put on the gel's base, up to 3 mm inside it).
// Every skip off: every pixel's ray, from the camera's near plane.
RenderSettings brute_force() {
  RenderSettings r = quiet_settings();
  r.cull = r.footprint = r.slab_limited_rays = r.rasterize = r.no_contact_cache = false;
  return r;
}

// Pixel for pixel, the same contact and depth (within a micrometre: the rasterizer's float
// planes against Embree's rays) as brute force, and the same count of clamped pixels.
void expect_as_brute_force(const SensorModel& sensor, std::shared_ptr<const ObjectShape> shape,
                           const SE3& pose, const std::string& what) {
  const RenderedFrame a = SensorRenderer(sensor, {shape}, quiet_settings()).render({pose}, 0);
  const RenderedFrame b = SensorRenderer(sensor, {shape}, brute_force()).render({pose}, 0);
  ASSERT_TRUE(b.stats.contact) << what;
  EXPECT_EQ(a.stats.contact_pixels, b.stats.contact_pixels) << what;
  EXPECT_EQ(a.stats.clamped_pixels, b.stats.clamped_pixels) << what;
  std::size_t differ = 0;
  for (std::size_t i = 0; i < a.images.depth.data.size(); ++i) {
    differ += a.images.mask.data[i] != b.images.mask.data[i] ||
              std::abs(a.images.depth.data[i] - b.images.depth.data[i]) > 1e-6f;
  }
  EXPECT_EQ(differ, 0u) << what;
}

std::shared_ptr<const ObjectShape> paper_object(const std::string& name) {
  return std::make_shared<ObjectShape>(
      load_mesh(std::string(PG_SOURCE_DIR) + "/meshes/" + name + ".glb"));
}

// An object pressed a little beyond the gel's 2 mm, where only a few pixels' rays start inside
// it. A small over-deep patch between the points a coarse pass sampled had been rasterized as
// if no ray started inside: its pixels got no hit, a hole of depth 0 at the deepest point,
// without a clamp counted (the cube corner). A ray started at the slab, inside one closed part
// of the toy human, met an overlapping part's front face next and read as outside: 123 holes
// at 240x320, 648 at 120x160. Both now as rays from the camera find them.
TEST(RenderSkip, PressesBeyondTheGelMatchBruteForce) {
  const SensorModel digit = flat_digit("digit"), digit_hi = flat_digit("digit_240x320");
  SensorModel curved = sensor_preset("digit");
  curved.gel.elastic.enabled = false;
  SensorModel curved_hi = sensor_preset("digit_240x320");
  curved_hi.gel.elastic.enabled = false;
  const auto quat = [](double w, double x, double y, double z) {
    return Eigen::Quaterniond(w, x, y, z).normalized();
  };
  expect_as_brute_force(curved, paper_object("cube"),
                        SE3(quat(0.913025046353, 0.323820613332, -0.246420068636, -0.0283306351228),
                            Eigen::Vector3d(0.002872, 0.0, 0.0143452)),
                        "cube corner");
  const auto human = paper_object("toy_human");
  expect_as_brute_force(curved_hi, human,
                        SE3(quat(0.973221172445, 0.0271807577457, -0.070860696989, 0.216980454272),
                            Eigen::Vector3d(0.009293292, 0.001393736, 0.017858455)),
                        "toy human at 240x320");
  expect_as_brute_force(
      curved, human,
      SE3(quat(0.0260005073479, 0.768295265841, -0.0838229020672, -0.634050533627),
          Eigen::Vector3d(-0.00239165, 0.007902975, 0.006047695)),
      "toy human at 120x160");
  // And seeded presses of a cube and the toy brick, 0-0.3 mm beyond the gel's limit.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const auto brick = paper_object("toy_brick"), cube = paper_object("cube");
  for (int k = 0; k < 16; ++k) {
    const auto& shape = k % 2 ? brick : cube;
    const SE3 R(quaternion_from_rpy({3.0 * u(rng), 3.0 * u(rng), 3.0 * u(rng)}),
                Eigen::Vector3d::Zero());
    double lowest = INFINITY;
    for (const auto& v : shape->mesh().vertices)
      lowest = std::min(lowest, (R * v.cast<double>()).z());
    const double press = digit.gel.max_indentation_m + 0.00015 * (1.0 + u(rng));
    const SE3 pose = SE3::Translation({0.003 * u(rng), 0.004 * u(rng), -lowest - press}) * R;
    expect_as_brute_force(k < 8 ? digit : digit_hi, shape, pose, "press " + std::to_string(k));
  }
}

// A pin far thinner than a millimetre, its tip pressed into the gel: a 0.2 mm ball of 40k
// triangles (more than the rasterizer is worth) and of 112. Its contact is a few pixels, which a
// coarse pass of rays 0.5 mm apart had missed altogether ("no contact", no warning).
TEST(RenderSkip, ThinFeaturesOfDenseMeshesAreFound) {
  for (const auto& [rings, segments] : {std::pair{100, 200}, std::pair{8, 7}}) {
    const auto pin = std::make_shared<ObjectShape>(make_uv_sphere(0.0002f, rings, segments));
    for (const auto& [x, y, press] :
         {std::tuple{0.0, 0.0, 0.0001}, std::tuple{0.00031, -0.00017, 0.00015},
          std::tuple{-0.0021, 0.0013, 0.00012}}) {
      const SE3 pose = SE3::Translation({x, y, 0.0002 - press});
      const std::string what = std::to_string(2 * rings * segments) + " triangles at " +
                               std::to_string(x) + ", " + std::to_string(y);
      const RenderedFrame a =
          SensorRenderer(flat_digit("digit"), {pin}, quiet_settings()).render({pose}, 0);
      EXPECT_TRUE(a.stats.contact) << what;
      expect_as_brute_force(flat_digit("digit"), pin, pose, what);
    }
  }
}

// The benchmark's sphere at 480x640, frame 178 of sphere_02: a ray grazing its outline met a
// face turned away first (a rounding error of the ray cast), was taken to start inside the
// sphere and clamped at 2 mm: one pixel of a 1.1 mm press, its normals wild and the clamp
// warned about. A ray can start inside only an object that reaches the camera.
TEST(RenderSkip, AGrazingRayIsNoContactAtTheGelsLimit) {
  SensorModel sensor = sensor_preset("digit");
  sensor.gel.elastic.enabled = false;
  sensor.camera = sensor.camera.resized(480, 640);
  const SE3 pose(Eigen::Quaterniond(0.910155048886, 0.313504012367, 0.164098227303, 0.215417717501)
                     .normalized(),
                 Eigen::Vector3d(0.00028068, -0.001334, 0.00483258));
  const RenderedFrame f =
      SensorRenderer(sensor, {paper_object("sphere_r6mm")}, brute_force()).render({pose}, 0);
  ASSERT_GT(f.stats.contact_pixels, 20000);
  EXPECT_EQ(f.stats.clamped_pixels, 0);
  expect_as_brute_force(sensor, paper_object("sphere_r6mm"), pose, "sphere_02 frame 178");
}

TEST(RenderBadInput, PenetrationBeyondTheGelIsClampedAndCounted) {
  SensorModel sensor = flat_digit("digit");
  RenderSettings s = quiet_settings();
  s.contact_points = true;
  const SensorRenderer r(sensor, {sphere_shape()}, s);
  const RenderedFrame f = r.render({pressed_sphere(0, 0, 0.004)}, 0);
  EXPECT_GT(f.stats.clamped_pixels, 100);
  float deepest = 0;
  for (float d : f.images.depth.data) deepest = std::max(deepest, d);
  EXPECT_NEAR(deepest, sensor.gel.max_indentation_m, 1e-9);
  for (float n : f.images.normal.data) ASSERT_TRUE(std::isfinite(n));
  const auto& points = f.contact_points_object.at(0);
  ASSERT_GT(points.size(), 100u);
  EXPECT_LT(int(points.size()), f.stats.contact_pixels);
  for (const auto& p : points) ASSERT_NEAR(p.norm(), kRadius, 2e-6);
}

// Closedness is a surface's own (triangles joined by edges): stray open triangles elsewhere in the
// file (a label, a leftover of the export), even one touching the sphere at a corner, and an open
// sheet inside it, leave the sphere's deep press as the sphere alone renders it, clamped at the
// gel's limit (the whole mesh had counted as open: a ring around a hole, no clamping).
TEST(RenderBadInput, AStrayOpenTriangleLeavesTheClosedPartsInside) {
  TriangleMesh mesh = make_uv_sphere(float(kRadius), 90, 180);
  const int n = int(mesh.vertices.size());
  // One stray triangle apart, one hanging from the sphere's top pole (a corner shared).
  mesh.vertices.insert(mesh.vertices.end(), {{0.0f, 0.0f, 0.02f},
                                             {0.001f, 0.0f, 0.02f},
                                             {0.0f, 0.001f, 0.02f},
                                             {0.001f, 0.0f, 0.01f},
                                             {0.0f, 0.001f, 0.01f}});
  mesh.triangles.emplace_back(n, n + 1, n + 2);
  ASSERT_NEAR(mesh.vertices[0].z(), float(kRadius), 1e-7f);
  mesh.triangles.emplace_back(0, n + 3, n + 4);
  // And an open sheet inside the sphere, 1 mm above the gel: a ray that starts inside the
  // sphere meets it before the sphere's far side (it had hidden that the ray started inside).
  const int m = int(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), {{-0.004f, -0.004f, 0.001f},
                                             {0.004f, -0.004f, 0.001f},
                                             {0.004f, 0.004f, 0.001f},
                                             {-0.004f, 0.004f, 0.001f}});
  mesh.triangles.emplace_back(m, m + 1, m + 2);
  mesh.triangles.emplace_back(m, m + 2, m + 3);
  const auto stray = std::make_shared<ObjectShape>(mesh);
  EXPECT_FALSE(stray->closed());
  EXPECT_TRUE(stray->any_part_closed());
  const auto alone = std::make_shared<ObjectShape>(make_uv_sphere(float(kRadius), 90, 180));
  const SensorModel sensor = flat_digit("digit");
  const SE3 deep = pressed_sphere(0, 0, 0.003);
  const RenderedFrame a = SensorRenderer(sensor, {alone}, quiet_settings()).render({deep}, 0);
  const RenderedFrame b = SensorRenderer(sensor, {stray}, quiet_settings()).render({deep}, 0);
  EXPECT_GT(a.stats.clamped_pixels, 100);
  EXPECT_EQ(b.stats.clamped_pixels, a.stats.clamped_pixels);
  EXPECT_EQ(b.stats.contact_pixels, a.stats.contact_pixels);
  EXPECT_EQ(b.images.depth.data, a.images.depth.data);
}

// A table-sized box pressed 0.5 mm at a 5 deg tilt: its face near the gel reaches 44 mm below
// it, behind the camera, where the rasterizer would project it mirrored (its contact had vanished
// from every output), and a plane of 2000 km, whose corners project beyond what float edge
// functions resolve (no contact either). Both render as the same face of a 10 cm box does.
TEST(RenderBadInput, ObjectsReachingBehindTheCameraRenderTheirContact) {
  const SensorModel sensor = flat_digit("digit");
  const auto render_box = [&](float half_m, double tilt) {
    TriangleMesh box = make_box({half_m, half_m, 0.01f});
    for (auto& v : box.vertices) v.z() += 0.01f;  // its bottom face at z = 0
    const SE3 pose(quaternion_from_rpy({0, tilt, 0}), Eigen::Vector3d(0, 0, -0.0005));
    return SensorRenderer(sensor, {std::make_shared<ObjectShape>(box)}, quiet_settings())
        .render({pose}, 0);
  };
  for (const auto& [half, tilt] : {std::pair{0.5f, 0.0873}, std::pair{1e6f, 0.0}}) {
    const RenderedFrame small = render_box(0.05f, tilt);
    const RenderedFrame large = render_box(half, tilt);
    ASSERT_GT(small.stats.contact_pixels, 1000);
    EXPECT_EQ(large.stats.contact_pixels, small.stats.contact_pixels) << half << " m";
    EXPECT_EQ(large.images.mask.data, small.images.mask.data) << half << " m";
    double most = 0;
    for (std::size_t i = 0; i < small.images.depth.data.size(); ++i)
      most =
          std::max(most, double(std::abs(large.images.depth.data[i] - small.images.depth.data[i])));
    EXPECT_LT(most, 1e-7) << half << " m [m]";
  }
}

TEST(RenderBadInput, MissingBackgroundImageNamesThePath) {
  RenderSettings s;
  s.background = "/no/such/bg.jpg";
  try {
    SensorRenderer r(sensor_preset("digit"), {sphere_shape()}, s);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/no/such/bg.jpg"), std::string::npos);
  }
}

// A background of another shape was stretched to the sensor's without a word.
TEST(RenderBadInput, ABackgroundOfAnotherShapeIsRefused) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("pg_test_landscape_bg_" + std::to_string(::getpid()) + ".png"))
                               .string();
  write_image(path, ImageU8(160, 120, 3));  // landscape, the DIGIT is 120x160
  RenderSettings s;
  s.background = path;
  try {
    SensorRenderer r(sensor_preset("digit"), {sphere_shape()}, s);
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(path + ": background image is 160x120, not of the "
                                                "sensor's shape (120x160, or any size of that "
                                                "shape;"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find(": it is turned by 90 degrees; turn it first"),
              std::string::npos)
        << e.what();
  }
  write_image(path, ImageU8(240, 320, 3));  // twice the sensor's size: fine
  EXPECT_NO_THROW(SensorRenderer(sensor_preset("digit"), {sphere_shape()}, s));
  std::filesystem::remove(path);
}

// A real background takes the imprint through a Gaussian of background_blur_m: 0 is no blur,
// and a larger sigma spreads the imprint wider and flatter (a sigma of 0 had still blurred, as a
// box of radius 1: at 120x160 the same images as the 0.2 mm default).
TEST(RenderColor, TheRealBackgroundsBlurIsTheSigmaGiven) {
  const std::string path = (std::filesystem::temp_directory_path() /
                            ("pg_test_grey_bg_" + std::to_string(::getpid()) + ".png"))
                               .string();
  write_image(path, ImageU8(120, 160, 3, 128));
  RenderSettings s = quiet_settings();
  s.background = path;
  const auto imprint = [&](double blur_m) {
    SensorModel sensor = flat_digit("digit");
    sensor.shading.background_blur_m = blur_m;
    const RenderedFrame f =
        SensorRenderer(sensor, {sphere_shape()}, s).render({pressed_sphere()}, 0);
    double energy = 0.0;
    int changed = 0;
    for (std::uint8_t v : f.images.color.data) {
      energy += (v - 128.0) * (v - 128.0);
      changed += v != 128;
    }
    return std::make_pair(energy, changed);
  };
  const auto [sharp, sharp_pixels] = imprint(0.0);
  const auto [soft, soft_pixels] = imprint(0.0002);
  const auto [softer, softer_pixels] = imprint(0.0005);
  std::filesystem::remove(path);
  std::printf(
      "imprint energy / changed channel values: blur 0 %.4g / %d, 0.2 mm %.4g / %d, "
      "0.5 mm %.4g / %d\n",
      sharp, sharp_pixels, soft, soft_pixels, softer, softer_pixels);
  EXPECT_GT(sharp, soft);
  EXPECT_GT(soft, softer);
  EXPECT_LT(sharp_pixels, soft_pixels);
  EXPECT_LT(soft_pixels, softer_pixels);
}

TEST(RenderOutputs, UnrequestedOutputsAreEmptyAndContactPointsLieOnTheObject) {
  RenderSettings s = quiet_settings();
  s.color = false;
  s.normal = false;
  s.contact_points = true;
  const SensorRenderer r(flat_digit("digit"), {sphere_shape()}, s);
  const RenderedFrame f = r.render({pressed_sphere()}, 0);
  EXPECT_TRUE(f.images.color.empty());
  EXPECT_TRUE(f.images.normal.empty());
  EXPECT_FALSE(f.images.depth.empty());
  ASSERT_EQ(f.contact_points_object.size(), 1u);
  ASSERT_GT(f.contact_points_object[0].size(), 100u);
  for (const auto& p : f.contact_points_object[0]) {
    EXPECT_NEAR(p.norm(), kRadius, 2e-6);          // on the (faceted) sphere
    EXPECT_LT(p.z(), -(kRadius - kPress) + 1e-6);  // its lower cap
  }
}

// Rendering into a reused frame rewrites only what changed since the frame it holds; the images
// must equal a fresh render's whatever that frame was.
TEST(RenderReuse, AReusedFrameHoldsTheSameImagesAsAFreshOne) {
  const auto cube = std::make_shared<ObjectShape>(make_box({0.004f, 0.004f, 0.004f}));
  const SE3 corner =
      SE3(quaternion_from_rpy({0.6, 0.5, 0.3}), Eigen::Vector3d(0.001, -0.002, 0.0052));
  const SE3 away = SE3::Translation({0, 0, 0.02});
  const std::vector<std::vector<SE3>> sequence = {{pressed_sphere(0.002, 0.003), away},
                                                  {pressed_sphere(-0.003, -0.004, 0.0015), away},
                                                  {away, away},
                                                  {away, corner},
                                                  {pressed_sphere(), corner},
                                                  {away, away}};
  for (bool noise : {true, false}) {
    RenderSettings s;
    s.noise = noise;
    s.contact_points = true;
    const SensorRenderer r(sensor_preset("digit"), {sphere_shape(), cube}, s);
    const SensorRenderer other(sensor_preset("digit"), {sphere_shape(), cube}, s);
    RenderedFrame reused;
    for (std::size_t k = 0; k < sequence.size(); ++k) {
      if (k == 3) other.render(sequence[0], 9, reused);  // last filled by another renderer
      if (k == 4) reused.images.normal = ImageF();       // an image moved out
      r.render(sequence[k], 100 + k, reused);
      const RenderedFrame fresh = r.render(sequence[k], 100 + k);
      const std::string what = "frame " + std::to_string(k) + (noise ? " with noise" : "");
      EXPECT_EQ(reused.images.color.data, fresh.images.color.data) << what;
      EXPECT_EQ(reused.images.normal.data, fresh.images.normal.data) << what;
      EXPECT_EQ(reused.images.depth.data, fresh.images.depth.data) << what;
      EXPECT_EQ(reused.images.mask.data, fresh.images.mask.data) << what;
      ASSERT_EQ(reused.contact_points_object.size(), fresh.contact_points_object.size());
      for (std::size_t o = 0; o < fresh.contact_points_object.size(); ++o)
        EXPECT_EQ(reused.contact_points_object[o].size(), fresh.contact_points_object[o].size());
      EXPECT_EQ(reused.stats.contact_pixels, fresh.stats.contact_pixels) << what;
    }
  }
}

// Shadows only take light away, and only around a dent deep enough to cast them.
TEST(RenderShadows, ShadowsOnlyDarkenAndFallBesideADeepPress) {
  RenderSettings lit = quiet_settings(), shadowed = quiet_settings();
  shadowed.shadows = true;
  const SensorRenderer a(sensor_preset("digit_240x320"), {sphere_shape()}, lit);
  const SensorRenderer b(sensor_preset("digit_240x320"), {sphere_shape()}, shadowed);
  const RenderedFrame no_contact = b.render({pressed_sphere(0, 0, -0.01)}, 0);
  EXPECT_EQ(no_contact.images.color.data,
            a.render({pressed_sphere(0, 0, -0.01)}, 0).images.color.data);
  // Pressed beyond the gel's 2 mm: the steep wall of the dent hides the rim beyond it from the
  // lights.
  const SE3 deep = pressed_sphere(0, 0, 0.004);
  const RenderedFrame fa = a.render({deep}, 0), fb = b.render({deep}, 0);
  int darker = 0, brighter = 0;
  for (std::size_t i = 0; i < fa.images.color.data.size(); ++i) {
    const int d = int(fb.images.color.data[i]) - int(fa.images.color.data[i]);
    brighter += d > 0;
    darker += d < -10;
  }
  EXPECT_EQ(brighter, 0);
  EXPECT_GT(darker, 100);
}

// Brute-force visibility of light `light` from the undeformed gel point seen through pixel i:
// the straight path to the light, in 4000 steps, is blocked where it passes farther from the
// camera than the dented surface (u > 0 at one of the four pixels around it), that surface
// interpolated bilinearly between the pixels. The lights are nearer to the camera than the gel:
// once nearer than the dent's shallowest point `shallowest` [m], the path stays unblocked.
bool brute_force_blocked(const GelRays& g, const CameraModel& cam, const ImageF& u, int i,
                         const Eigen::Vector3f& light, float shallowest) {
  const Eigen::Vector3f p = g.point(i, 0.0f);
  for (int s = 1; s < 4000; ++s) {
    const Eigen::Vector3f q = p + (light - p) * (float(s) / 4000.0f);
    const float depth = q.z() - g.origin_sensor.z();
    if (depth < shallowest) break;
    const float fx = float(cam.fx) * q.x() / depth + float(cam.cx);
    const float fy = float(cam.fy) * q.y() / depth + float(cam.cy);
    const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
    if (x0 < 0 || y0 < 0 || x0 + 1 >= g.width || y0 + 1 >= g.height) continue;
    const float ax = fx - float(x0), ay = fy - float(y0);
    float surface = 0.0f, dented = 0.0f;
    for (int dy = 0; dy <= 1; ++dy)
      for (int dx = 0; dx <= 1; ++dx) {
        const float w = (dx ? ax : 1.0f - ax) * (dy ? ay : 1.0f - ay);
        const float uu = u.at(x0 + dx, y0 + dy);
        surface += w * (g.t_gel[std::size_t(g.index(x0 + dx, y0 + dy))] - uu);
        dented = std::max(dented, uu);
      }
    if (dented > 0.0f && depth > surface + 1e-6f) return true;
  }
  return false;
}

// The dent also shadows the undeformed gel beside it, away from each light, and only there; a
// reused frame keeps no shadow of an earlier frame's contact.
TEST(RenderShadows, ADentShadowsTheUndeformedGelBesideItAwayFromEachLight) {
  const SensorModel sensor = sensor_preset("digit_240x320");
  RenderSettings lit = quiet_settings(), shadowed = quiet_settings();
  shadowed.shadows = true;
  const SensorRenderer a(sensor, {sphere_shape()}, lit), b(sensor, {sphere_shape()}, shadowed);
  const SE3 deep = pressed_sphere(0.001, -0.001, 0.004);
  const RenderedFrame fa = a.render({deep}, 0), fb = b.render({deep}, 0);
  const ImageU8& bg = b.background_color_u8();
  const ImageF& u = fb.images.depth;
  const int w = u.width, h = u.height;
  // Undeformed pixels whose neighbours are undeformed too: normal and shading as without
  // contact, unless shadowed.
  auto undeformed = [&](int x, int y) {
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const int xx = std::clamp(x + dx, 0, w - 1), yy = std::clamp(y + dy, 0, h - 1);
        if (u.at(xx, yy) > 0.0f) return false;
      }
    return true;
  };
  const GelRays g = make_gel_rays(sensor.camera, sensor.gel);
  PixelRect dent;
  float shallowest = INFINITY;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (u.at(x, y) > 0.0f) {
        dent.include(x, y);
        shallowest = std::min(shallowest, g.t_gel[std::size_t(g.index(x, y))] - u.at(x, y));
      }
  ASSERT_FALSE(dent.empty());
  const Eigen::Vector2f centre(0.5f * float(dent.x0 + dent.x1), 0.5f * float(dent.y0 + dent.y1));
  std::vector<int> darker(sensor.lights.size(), 0), away(sensor.lights.size(), 0);
  int blocked = 0, disagree = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (!undeformed(x, y)) continue;
      for (int c = 0; c < 3; ++c) {
        ASSERT_EQ(fa.images.color.at(x, y, c), bg.at(x, y, c)) << "shadows off: " << x << "," << y;
        ASSERT_LE(fb.images.color.at(x, y, c), bg.at(x, y, c)) << x << "," << y;
      }
      const bool far =
          x < dent.x0 - 80 || x >= dent.x1 + 80 || y < dent.y0 - 80 || y >= dent.y1 + 80;
      const int i = g.index(x, y);
      for (std::size_t k = 0; k < sensor.lights.size(); ++k) {
        const Eigen::Vector3f light = sensor.lights[k].position_m.cast<float>();
        const bool dark = fb.images.color.at(x, y, int(k)) < bg.at(x, y, int(k));
        if (far) {
          EXPECT_FALSE(dark) << "far from the contact: " << x << "," << y;
          continue;
        }
        const Eigen::Vector3f n(fb.images.normal.at(x, y, 0), fb.images.normal.at(x, y, 1),
                                fb.images.normal.at(x, y, 2));
        const bool lit_side = n.dot(light - g.point(i, 0.0f)) < 0.0f;
        const bool expected =
            lit_side && brute_force_blocked(g, sensor.camera, u, i, light, shallowest);
        blocked += expected;
        disagree += expected != dark;
        if (!dark) continue;
        ++darker[k];
        // Away from the light: the light lies on the other side of the dent's centre.
        const Eigen::Vector2f to_light(float(light.x()), float(light.y()));
        away[k] += (Eigen::Vector2f(float(x), float(y)) - centre).dot(to_light) < 0.0f;
      }
    }
  }
  for (std::size_t k = 0; k < sensor.lights.size(); ++k) {
    EXPECT_GT(darker[k], 100) << "light " << k;
    EXPECT_EQ(away[k], darker[k]) << "light " << k;
  }
  // The march and the brute force disagree only on paths that graze the dent (10 of 762 pairs).
  EXPECT_GT(blocked, 300);
  EXPECT_LE(disagree, blocked / 50) << disagree << " of " << blocked << " blocked pairs disagree";

  // A moving contact: a reused frame holds what a fresh one does, with noise and without, and
  // blended into a real background.
  ImageU8 real(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c) real.at(x, y, c) = std::uint8_t((x + 2 * y + 50 * c) % 256);
  const std::string real_path = ::testing::TempDir() + "shadow_test_background.png";
  write_image(real_path, real);
  const std::vector<SE3> sequence = {deep, pressed_sphere(-0.003, 0.004, 0.004),
                                     pressed_sphere(0.0, 0.0, -0.01), pressed_sphere(0.003, 0.0)};
  for (int variant = 0; variant < 3; ++variant) {
    RenderSettings s = shadowed;
    s.noise = variant == 1;
    if (variant == 2) s.background = real_path;
    const SensorRenderer r(sensor, {sphere_shape()}, s);
    RenderedFrame reused;
    for (std::size_t k = 0; k < sequence.size(); ++k) {
      r.render({sequence[k]}, 5 + k, reused);
      EXPECT_EQ(reused.images.color.data, r.render({sequence[k]}, 5 + k).images.color.data)
          << "frame " << k << " variant " << variant;
    }
  }
}

// The renderer's C++ API given what no scene or sensor file could hold (an audit's probes, each
// of which had crashed, corrupted memory, looped for ever or rendered garbage without a word):
// each is refused with an error that says what.
TEST(RenderBadInput, InputsSetInCppAreRefusedAsTheFilesWouldBe) {
  const auto message = [](const std::function<void()>& call) -> std::string {
    try {
      call();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "(accepted)";
  };
  const auto says = [&](const std::function<void()>& call, const std::string& what) {
    const std::string m = message(call);
    EXPECT_NE(m.find(what), std::string::npos) << "expected '" << what << "', got '" << m << "'";
  };
  const SensorModel digit = flat_digit("digit");
  // A camera left unset (fx = 0 had written past the gel's bins), an empty image, no distance.
  SensorModel unset = digit;
  unset.camera = CameraModel{};
  says([&] { SensorRenderer(unset, {sphere_shape()}, quiet_settings()); },
       "SensorRenderer: sensor");
  // ... and wherever else a sensor model is taken (fx = 0 had read +inf bounds, the whole gel).
  says([&] { ShadingInversion inversion(unset, false); }, "ShadingInversion: sensor");
  says([&] { NormalBounds bounds(unset); }, "NormalBounds: sensor");
  says([&] { visible_gel_area(unset); }, "visible_gel_area: sensor");
  SensorModel narrow = digit;
  narrow.camera.width = 0;
  says([&] { SensorRenderer(narrow, {sphere_shape()}, quiet_settings()); }, "width");
  SensorModel flat_indentation = digit;
  flat_indentation.gel.max_indentation_m = 0;
  EXPECT_THROW(SensorRenderer(flat_indentation, {sphere_shape()}, quiet_settings()), InputError);
  says([&] { SensorRenderer(digit, {nullptr}, quiet_settings()); }, "object 0 is null");
  // Meshes built in C++: an index past the vertices (read out of bounds), a NaN vertex.
  TriangleMesh bad_index = make_box({0.004f, 0.004f, 0.004f});
  bad_index.triangles[3][1] = 1000000;
  says([&] { ObjectShape shape(bad_index); }, "triangle 3 has vertex index 1000000");
  TriangleMesh nan_vertex = make_box({0.004f, 0.004f, 0.004f});
  nan_vertex.vertices[5].x() = NAN;
  says([&] { ObjectShape shape(nan_vertex); }, "vertex 5 is not finite");
  // A closed mesh turned inside out (its corners clockwise seen from outside) had pressed
  // nothing; a cavity, a closed surface facing inward inside another, is one by design.
  TriangleMesh inside_out = make_box({0.004f, 0.004f, 0.004f});
  for (Eigen::Vector3i& t : inside_out.triangles) std::swap(t[1], t[2]);
  says([&] { ObjectShape shape(inside_out); }, "faces inward");
  TriangleMesh hollow_box = make_box({0.008f, 0.008f, 0.008f});
  const int outer_vertices = int(hollow_box.vertices.size());
  for (const Eigen::Vector3f& v : inside_out.vertices) hollow_box.vertices.push_back(v);
  for (const Eigen::Vector3i& t : inside_out.triangles) {
    hollow_box.triangles.push_back(t + Eigen::Vector3i::Constant(outer_vertices));
  }
  EXPECT_NO_THROW(ObjectShape shape(hollow_box));
  EXPECT_THROW(make_uv_sphere(0.005f, 1, 8), std::invalid_argument);
  EXPECT_THROW(make_box({-0.004f, 0.004f, 0.004f}), std::invalid_argument);
  // A pose that is not one (NaN, or ROS's unset zero quaternion) had rendered as no contact or
  // as the identity.
  const SensorRenderer renderer(digit, {sphere_shape()}, quiet_settings());
  says([&] { renderer.render({SE3::Translation({NAN, 0, 0})}, 0); }, "object 0's pose");
  SE3 unset_pose = pressed_sphere();
  unset_pose = SE3(Eigen::Quaterniond(0, 0, 0, 0), unset_pose.translation());
  EXPECT_THROW(renderer.render({unset_pose}, 0), InputError);
  EXPECT_TRUE(renderer.render({pressed_sphere()}, 0).stats.contact) << "a pose that is one";
  // A frame buffer of another size than its shape says, read through the shading's inverse.
  const ShadingInversion inversion(digit, false);
  ImageU8 hollow(digit.camera.width, digit.camera.height, 3);
  hollow.data.clear();
  says([&] { inversion.normals(hollow, renderer.background_color_u8()); }, "holds 0 values");
  // Samplers: a spacing that is not positive had placed a point a triangle.
  const TriangleMesh box = make_box({0.004f, 0.004f, 0.004f});
  for (const double spacing : {0.0, -1e-4, double(NAN)}) {
    EXPECT_THROW(sample_surface(box, spacing), std::invalid_argument) << spacing;
    EXPECT_THROW(surface_grid(box, spacing), std::invalid_argument) << spacing;
  }
  // Random presses that can never end (no attempt allowed) or go nowhere (a NaN centre).
  RandomPressOptions endless;
  endless.attempts = -1;
  says([&] { random_presses(surface_grid(box, 5e-4), digit.gel, endless); }, "attempts at least 1");
  RandomPressOptions nowhere;
  nowhere.centre_m.x() = NAN;
  EXPECT_THROW(random_presses(surface_grid(box, 5e-4), digit.gel, nowhere), InputError);
  // A scene renderer: frames, sensors and objects it does not have, outputs of no known name, a
  // tracked object past the list.
  Scene scene;
  scene.path = "scene set in C++";
  scene.frames = 3;
  SceneSensor sensor;
  sensor.model = digit;
  scene.sensors.push_back(sensor);
  SceneObject object;
  object.mesh_path = std::string(PG_SOURCE_DIR) + "/meshes/sphere_r6mm.glb";
  scene.objects.push_back(object);
  const SceneRenderer scene_renderer(scene);
  EXPECT_EQ(scene_renderer.render_frame(2).size(), 1u);
  EXPECT_THROW(scene_renderer.render_frame(3), std::out_of_range);
  EXPECT_THROW(scene_renderer.render_frame(-1), std::out_of_range);
  EXPECT_THROW(scene_renderer.sensor(3), std::out_of_range);
  EXPECT_THROW(scene_renderer.object_shape(7), std::out_of_range);
  RenderOverrides typo;
  typo.outputs = {"colour"};
  says([&] { SceneRenderer r(scene, typo); }, "unknown output 'colour' (known: color,");
  RenderOverrides negative;
  negative.width = -5;
  says([&] { SceneRenderer r(scene, negative); }, "none may be negative");
  Scene past = scene;
  past.tracked_object = 5;
  says([&] { SceneRenderer r(past); }, "tracked_object 5 is not one of its 1 objects");
}

}  // namespace
}  // namespace pg
