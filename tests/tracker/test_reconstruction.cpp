// Render -> reconstruct round trip: the renderer's ground-truth normals of the paper's objects,
// integrated and back-projected by the tracker, give a cloud on the true object surface.
#include <gtest/gtest.h>

#include "pg/core/gel_rays.h"
#include "pg/core/image_change.h"
#include "pg/sim/primitives.h"
#include "pg/tracker/contact_cloud.h"
#include "pg/tracker/degeneracy.h"
#include "pg/tracker/depth_from_normals.h"
#include "pg/tracker/kd_tree.h"
#include "tracker_test_util.h"

namespace pg {
namespace {

using namespace pg::test;

// Reconstructs from the rendered normals (reference: the renderer's no-contact normals or, when
// renderer_reference is false, the gel model) and returns the cloud in the object frame.
PointCloud reconstruct_object_cloud(const RenderCase& rc, const SE3& T_sensor_object,
                                    bool renderer_reference) {
  const RenderedFrame f = render(rc, T_sensor_object);
  ContactCloudBuilder builder(rc.sensor, test::all_contact_pixels(),
                              renderer_reference ? rc.renderer->undeformed_normals() : ImageF());
  const ContactFrame frame = builder.build(f.images.normal);
  EXPECT_EQ(frame.status, ContactStatus::kContact);
  return transform_cloud(T_sensor_object.inverse(), frame.cloud_sensor);
}

void expect_on_surface(const std::string& name, const std::vector<double>& d, int min_points) {
  double max = 0;
  for (double x : d) max = std::max(max, x);
  EXPECT_GT(int(d.size()), min_points) << name;
  EXPECT_LT(rms(d), 0.05e-3) << name << ": RMS distance to the surface " << rms(d) * 1e3
                             << " mm over " << d.size() << " points (max " << max * 1e3 << " mm)";
  std::printf("  %-32s %5zu points, RMS %.4f mm, max %.4f mm\n", name.c_str(), d.size(),
              rms(d) * 1e3, max * 1e3);
}

TEST(RoundTrip, SphereCloudLiesOnTheSphere) {
  const double R = 0.006;
  const auto sphere = std::make_shared<ObjectShape>(make_uv_sphere(float(R), 90, 180));
  for (const char* preset : {"digit", "digit_240x320"}) {
    const RenderCase rc = make_render_case(preset, sphere);
    // Pressed 1 mm, off the gel centre.
    const SE3 pose =
        SE3::Translation({0.001, -0.0015, 0}) * press_pose({0, 0, -0.006}, {0, 0, -1}, 0.001);
    for (bool ref : {true, false}) {
      const std::string name =
          std::string("sphere ") + preset + (ref ? " render-ref" : " model-ref");
      const PointCloud cloud_object = reconstruct_object_cloud(rc, pose, ref);
      // The UV sphere's facets lie within R (1 - cos(pi / 180)) = 0.9 um of the analytic sphere.
      std::vector<double> d;
      for (const auto& p : cloud_object.points) d.push_back(std::abs(p.cast<double>().norm() - R));
      expect_on_surface(name, d, 300);
    }
  }
}

// The renderer's default, elastic gel rounds the contact's edge (sink-in): the gel there is
// indented but not touching, so those pixels lie off the object. The default contact threshold
// (0.1 mm) keeps the cloud within the target anyway.
TEST(RoundTrip, SphereCloudLiesOnTheSphereWithTheElasticGel) {
  const double R = 0.006;
  const auto sphere = std::make_shared<ObjectShape>(make_uv_sphere(float(R), 90, 180));
  for (const char* preset : {"digit", "digit_240x320"}) {
    RenderCase rc = make_render_case(preset, sphere);
    rc.sensor.gel.elastic = ElasticModel();
    RenderSettings settings;
    settings.noise = false;
    settings.color = false;
    rc.renderer = std::make_unique<SensorRenderer>(rc.sensor, std::vector{rc.shape}, settings);
    const SE3 pose = SE3::Translation({0.001, -0.0015, R - 0.001});
    const PointCloud cloud_object = reconstruct_object_cloud(rc, pose, true);
    std::vector<double> d;
    for (const auto& p : cloud_object.points) d.push_back(std::abs(p.cast<double>().norm() - R));
    expect_on_surface(std::string("sphere, elastic gel ") + preset, d, 300);
  }
}

TEST(RoundTrip, CubeCornerCloudLiesOnTheCube) {
  const auto cube = mesh_shape("cube.glb");
  for (const char* preset : {"digit", "digit_240x320"}) {
    const RenderCase rc = make_render_case(preset, cube);
    // The rounded corner's tip (corner sphere of radius 1 mm centred at 9 mm), pressed 1.5 mm.
    const double tip = 0.009 + 0.001 / std::sqrt(3.0);
    const SE3 pose = press_pose({tip, tip, tip}, {1, 1, 1}, 0.0015, 0.3);
    const PointCloud cloud_object = reconstruct_object_cloud(rc, pose, true);
    expect_on_surface(std::string("cube corner ") + preset,
                      distances_to_mesh(cube->mesh(), cloud_object.points), 300);
  }
}

// The renderer's normal is the central difference of its neighbours' surface points, so the
// parity integration inverts it: the rendered indentation comes back to float precision, kinks
// (the rim, the cube's edges) included. The averaged integration smooths each kink by about a
// pixel; it is checked to be measurably off here, so this test notices if the renderer's normals
// change to something the parity integration no longer inverts.
TEST(RoundTrip, ParityIntegrationRecoversTheRenderedIndentation) {
  const auto cube = mesh_shape("cube.glb");
  const double tip = 0.009 + 0.001 / std::sqrt(3.0), h = 0.009 + 0.001 / std::sqrt(2.0);
  struct Case {
    const char* name;
    SE3 pose;
  };
  for (const char* preset : {"digit", "digit_240x320"}) {
    const RenderCase rc = make_render_case(preset, cube);
    for (const Case& c : {Case{"corner", press_pose({tip, tip, tip}, {1, 1, 1}, 0.0012, 0.3)},
                          Case{"edge", press_pose({h, h, 0.002}, {1, 1, 0}, 0.0008, 0.2)}}) {
      const RenderedFrame f = render(rc, c.pose);
      double max_err[2] = {0, 0}, sum_sq[2] = {0, 0};
      int pixels = 0;
      for (int k = 0; k < 2; ++k) {
        DepthOptions options;
        options.integration = k == 0 ? DepthIntegration::kParity : DepthIntegration::kAveraged;
        DepthFromNormals solver(rc.sensor, options, rc.renderer->undeformed_normals());
        DepthResult out;
        solver.compute(f.images.normal, out);
        pixels = 0;
        for (std::size_t i = 0; i < out.depth.data.size(); ++i) {
          const double u = f.images.depth.data[i];
          if (!(u > 0)) continue;
          const double e = std::abs(double(out.depth.data[i]) - u);
          max_err[k] = std::max(max_err[k], e);
          sum_sq[k] += e * e;
          ++pixels;
        }
      }
      const std::string what = std::string(preset) + " " + c.name;
      ASSERT_GT(pixels, 200) << what;
      EXPECT_LT(max_err[0], 0.2e-6) << what << ": parity integration, largest error [m]";
      const double averaged_rms = std::sqrt(sum_sq[1] / pixels);
      EXPECT_GT(averaged_rms, 2e-6) << what << ": averaged integration, RMS error [m]";
      std::printf("  %-20s %5d pixels: parity max %.3f um, averaged RMS %.1f um\n", what.c_str(),
                  pixels, max_err[0] * 1e6, averaged_rms * 1e6);
    }
  }
}

// A stud's rim on the rigid gel is a wall, which the rendered normals (central differences over
// two pixels) show ever steeper as the pixels get finer. With the guard of eq. 4 fixed at n.d >=
// 0.2 the rims' normals were clamped at 240x320 and 480x640 (this press: 6 and 441 pixels, the
// depth 8 and 98 um off) and the integrated depth lost the wall's height (toy_brick_05 tracked
// 0.009 and 0.036 rad off instead of 0.0004); the guard now widens with the resolution
// (DepthFromNormals::min_normal_dot_ray), and holds as given at 120x160.
TEST(RoundTrip, ParityIntegrationRecoversAStudsRimAtEveryResolution) {
  const auto brick = mesh_shape("toy_brick.glb");
  // Upside down, its studs pressed into the gel, as toy_brick_05 starts: at 120x160 no rim is
  // steeper than the guard.
  const SE3 pose = pose_from_position_rpy({0.00044, 0.00082, 0.0049}, {kPi, 0, 1.4036});
  for (const int scale : {1, 2, 4}) {
    SensorModel sensor = sensor_preset("digit");
    sensor.camera = sensor.camera.resized(120 * scale, 160 * scale);
    const RenderCase rc = make_render_case(sensor, brick);
    const RenderedFrame f = render(rc, pose);
    DepthFromNormals solver(rc.sensor, DepthOptions(), rc.renderer->undeformed_normals());
    if (scale == 1) {
      EXPECT_EQ(solver.min_normal_dot_ray(), float(DepthOptions().min_normal_dot_ray));
    }
    DepthResult out;
    solver.compute(f.images.normal, out);
    double max_err = 0;
    int pixels = 0;
    for (std::size_t i = 0; i < out.depth.data.size(); ++i) {
      const double u = f.images.depth.data[i];
      if (!(u > 0)) continue;
      max_err = std::max(max_err, std::abs(double(out.depth.data[i]) - u));
      ++pixels;
    }
    const std::string what = std::to_string(120 * scale) + "x" + std::to_string(160 * scale);
    ASSERT_GT(pixels, 200 * scale * scale) << what;
    EXPECT_EQ(out.clamped_normals, 0) << what;
    EXPECT_LT(max_err, 0.5e-6) << what << ": largest error [m]";
    std::printf("  %-8s %6d pixels, guard n.d >= %.3f: largest error %.3f um\n", what.c_str(),
                pixels, solver.min_normal_dot_ray(), max_err * 1e6);
  }
}

// Off the camera's axis a pixel sees walls that lean past the vertical (n.z <= 0) and still face
// its ray (n.d > 0): the toy brick's stud rims on the GelSight Mini, whose camera is close and
// wide. Such normals are the surface's, not a broken pixel's: they are used (clamped by the
// guard where steeper than it), where the test n.z > 0 had rejected 459 in this frame. A normal
// seen from behind (n.d <= 0) is still rejected.
TEST(RoundTrip, WallsLeaningPastTheVerticalOffAxisAreUsed) {
  const auto brick = mesh_shape("toy_brick.glb");
  const SE3 pose = pose_from_position_rpy({0.00044, 0.00082, 0.0046}, {kPi, 0, 1.4036});
  const RenderCase rc = make_render_case("gelsight_mini", brick);
  RenderedFrame f = render(rc, pose);
  const GelRays rays = make_gel_rays(rc.sensor.camera, rc.sensor.gel);
  int leaning = 0, behind = 0;
  std::size_t last_leaning = 0;
  for (std::size_t i = 0; i < rays.dir_sensor.size(); ++i) {
    const Eigen::Vector3f n(&f.images.normal.data[3 * i]);
    if (n.z() <= 0) {
      ++leaning;
      last_leaning = i;
    }
    behind += n.dot(rays.dir_sensor[i]) <= 0;
  }
  ASSERT_GT(leaning, 100);
  ASSERT_EQ(behind, 0);
  DepthFromNormals solver(rc.sensor, DepthOptions(), rc.renderer->undeformed_normals());
  DepthResult out;
  solver.compute(f.images.normal, out);
  EXPECT_EQ(out.invalid_normals, 0);
  std::printf("  %d pixels leaning past the vertical, %d clamped by the guard\n", leaning,
              out.clamped_normals);
  const Eigen::Vector3f flipped = -rays.dir_sensor[last_leaning].normalized();
  for (int c = 0; c < 3; ++c) f.images.normal.data[3 * last_leaning + c] = flipped[c];
  solver.compute(f.images.normal, out);
  EXPECT_EQ(out.invalid_normals, 1);
}

TEST(RoundTrip, ToyBrickCloudLiesOnTheBrick) {
  const auto brick = mesh_shape("toy_brick.glb");
  for (const char* preset : {"digit", "digit_240x320"}) {
    const RenderCase rc = make_render_case(preset, brick);
    // A top corner of the body, tilted so that the nearest stud's rim touches too.
    const SE3 pose = press_pose({0.0159, 0.0079, 0.00395}, {1, 1, 2}, 0.0012, 0.2);
    const PointCloud cloud_object = reconstruct_object_cloud(rc, pose, true);
    expect_on_surface(std::string("toy brick ") + preset,
                      distances_to_mesh(brick->mesh(), cloud_object.points), 200);
    int on_stud = 0;  // stud tops are at z = 5.65 mm, the body top at 3.95 mm
    for (const auto& p : cloud_object.points) on_stud += p.z() > 0.0042f;
    EXPECT_GT(on_stud, 50) << "the pose should press a stud's rim as well as the body corner";
  }
}

// The contact's core (MaskOptions::core_relative_depth): on a deep corner press the core alone
// constrains the pose as well as the whole contact, so the cloud keeps only the core; on an edge
// pressed just deep enough for the flat faces' shallow strips to show the turn about the edge,
// the core alone would leave that turn free, so the cloud keeps the whole contact.
struct CoreCase {
  ContactFrame whole, core_alone, chosen;
  int whole_free = 0, core_free = 0;  // unconstrained directions of each cloud
};
CoreCase core_case(const RenderCase& rc, const SE3& pose) {
  const RenderedFrame f = render(rc, pose);
  const ImageF& reference = rc.renderer->undeformed_normals();
  ContactCloudOptions core_only = all_contact_pixels();
  core_only.mask.relative_depth = ContactCloudOptions().mask.core_relative_depth;
  CoreCase c;
  c.whole = ContactCloudBuilder(rc.sensor, all_contact_pixels(), reference).build(f.images.normal);
  c.core_alone = ContactCloudBuilder(rc.sensor, core_only, reference).build(f.images.normal);
  c.chosen =
      ContactCloudBuilder(rc.sensor, ContactCloudOptions(), reference).build(f.images.normal);
  const double ratio = ContactCloudOptions().min_eigenvalue_ratio;
  c.whole_free = analyse_cloud_degeneracy(c.whole.cloud_sensor, ratio).unconstrained;
  c.core_free = analyse_cloud_degeneracy(c.core_alone.cloud_sensor, ratio).unconstrained;
  std::printf("  whole contact %zu points, %d unconstrained; core %zu points, %d; kept: %s\n",
              c.whole.cloud_sensor.size(), c.whole_free, c.core_alone.cloud_sensor.size(),
              c.core_free, c.chosen.core ? "the core" : "the whole contact");
  return c;
}

bool same_points(const PointCloud& a, const PointCloud& b) {
  return a.points == b.points && a.normals == b.normals;
}

TEST(ContactCore, DeepCornerKeepsTheCore) {
  const RenderCase rc = make_render_case("digit", mesh_shape("cube.glb"));
  const double tip = 0.009 + 0.001 / std::sqrt(3.0);
  const SE3 pose = press_pose({tip, tip, tip}, {1, 1, 1}, 0.0012, 0.3);
  const CoreCase c = core_case(rc, pose);
  ASSERT_EQ(c.whole.status, ContactStatus::kContact);
  EXPECT_EQ(c.whole_free, 0);
  EXPECT_EQ(c.core_free, 0);
  EXPECT_TRUE(c.chosen.core);
  EXPECT_TRUE(same_points(c.chosen.cloud_sensor, c.core_alone.cloud_sensor));
  EXPECT_LT(c.chosen.cloud_sensor.size(), c.whole.cloud_sensor.size() * 9 / 10);
  EXPECT_EQ(c.chosen.mask.pixels, c.whole.mask.pixels) << "the mask stays the whole contact";
  // A reused frame does not keep the flag: the no-contact image after the press.
  ContactCloudBuilder builder(rc.sensor, ContactCloudOptions(), rc.renderer->undeformed_normals());
  ContactFrame frame;
  builder.build(render(rc, pose).images.normal, frame);
  ASSERT_TRUE(frame.core);
  builder.build(rc.renderer->undeformed_normals(), frame);
  EXPECT_EQ(frame.status, ContactStatus::kNoContact);
  EXPECT_FALSE(frame.core);
  EXPECT_TRUE(frame.cloud_sensor.empty());
}

TEST(ContactCore, EdgeKeepsTheWholeContactWhereOnlyItShowsTheTurn) {
  const RenderCase rc = make_render_case("digit", mesh_shape("cube.glb"));
  const double h = 0.009;  // the rounding's axis: x = y = 9 mm, along z
  const Eigen::Vector3d tip(h + 0.001 / std::sqrt(2.0), h + 0.001 / std::sqrt(2.0), 0.002);
  const CoreCase c = core_case(rc, press_pose(tip, {1, 1, 0}, 0.00075, 0.3));
  EXPECT_EQ(c.whole_free, 1) << "the slide along the edge";
  EXPECT_EQ(c.core_free, 2) << "the slide and the turn about the edge";
  EXPECT_FALSE(c.chosen.core);
  EXPECT_TRUE(same_points(c.chosen.cloud_sensor, c.whole.cloud_sensor));
  // Deeper, the core shows the turn too and is kept.
  const CoreCase deeper = core_case(rc, press_pose(tip, {1, 1, 0}, 0.001, 0.3));
  EXPECT_EQ(deeper.core_free, 1);
  EXPECT_TRUE(deeper.chosen.core);
}

// With learned normals a frame goes to the network only when the pixels that changed beyond the
// camera's noise, in regions of a contact's size (not specks), reach the smallest contact
// (track_dataset). That must never drop a contact the mask can use: a sphere and a cube corner
// pressed ever deeper (rigid gel, noise sigma 7 against the noise-free reference), at 120x160 and
// at 60x80, where the smallest contact is 5 px: at the first depth at which the indentation
// exceeds the mask's 0.1 mm over that many pixels, enough pixels have changed.
TEST(ChangeRegions, AContactTheMaskCanUseIsNeverTakenForNoChange) {
  const std::pair<std::string, Eigen::Vector3d> tips[] = {
      {"sphere_r6mm.glb", Eigen::Vector3d(0, 0, -1)}, {"cube.glb", Eigen::Vector3d(-1, -1, -1)}};
  for (const auto& [mesh, direction] : tips) {
    const std::shared_ptr<const ObjectShape> shape = mesh_shape(mesh);
    // The tip: the mesh's point farthest along the direction.
    Eigen::Vector3d tip = shape->mesh().vertices[0].cast<double>();
    for (const auto& v : shape->mesh().vertices) {
      if (v.cast<double>().dot(direction) > tip.dot(direction)) tip = v.cast<double>();
    }
    for (const int width : {120, 60}) {
      SensorModel sensor = sensor_preset("digit");
      sensor.camera = sensor.camera.resized(width, width * 4 / 3);
      sensor.gel.elastic.enabled = false;
      RenderSettings settings;
      settings.noise = true;
      const SensorRenderer renderer(sensor, {shape}, settings);
      const ContactCloudBuilder builder(sensor, ContactCloudOptions{});
      const int min_pixels = builder.min_contact_pixels();
      bool reached = false;
      for (double press = 0.05e-3; press < 0.5e-3 && !reached; press += 0.01e-3) {
        const RenderedFrame f = renderer.render({press_pose(tip, direction, press)}, 7);
        const int deep = int(std::count_if(f.images.depth.data.begin(), f.images.depth.data.end(),
                                           [](float u) { return u > 1e-4f; }));
        if (deep < min_pixels) continue;
        reached = true;
        const ChangedRegions changes =
            changed_regions(f.images.color, renderer.background_color_u8());
        EXPECT_GE(changes.pixels_in_regions_of(std::min(kSpeckPixels, min_pixels)), min_pixels)
            << mesh << " at " << width << " px wide, " << press * 1e3 << " mm: " << deep
            << " px deeper than 0.1 mm, " << changes.changed << " changed";
      }
      EXPECT_TRUE(reached) << mesh << " at " << width;
    }
  }
}

}  // namespace
}  // namespace pg
