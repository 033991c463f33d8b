// Stress: degenerate geometry (what a contact patch cannot show) and scale (objects from 1 mm to
// 50 mm, presses from 1 um to past the gel, contact edges nearly parallel to the rays). The
// assertions: nothing non-finite, the degeneracy is reported, unobservable motion does not run
// away, and what is observable is still tracked.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "pg/sim/primitives.h"
#include "stress_support.h"

namespace pg::stress {
namespace {

using test::mesh_shape;

std::shared_ptr<const ObjectShape> shape(TriangleMesh mesh) {
  return std::make_shared<ObjectShape>(std::move(mesh));
}

// z error of the object's origin in S: the direction a pressed face always shows.
double z_error_m(const StressFrame& f) {
  return std::abs(f.estimate.T_world_object.translation().z() -
                  f.T_world_object_gt.translation().z());
}

int max_unconstrained(const StressRun& run) {
  int worst = 0;
  for (const auto& f : run.frames) worst = std::max(worst, f.estimate.unconstrained_directions);
  return worst;
}

// A 20 mm cube face down, pressed from 0.5 to 0.8 mm while slid 2 mm along x and spun 0.2 rad
// about z over 60 frames: slide and spin are invisible to a flat patch, the deepening is not (an
// estimate that stayed put would end 0.3 mm off in z).
TEST(StressGeometry, FlatFaceSlidAndSpun) {
  const ClosedLoop& loop = cube_loop();
  std::vector<SE3> poses;
  for (int f = 0; f < 60; ++f) {
    const double s = f / 59.0;
    poses.push_back(SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * s, Eigen::Vector3d::UnitZ())),
                        Eigen::Vector3d(0.002 * s, 0, 0.010 - 0.0005 - 0.0003 * s)));
  }
  const StressRun run = loop.track(poses);
  run.print("FlatFaceSlidAndSpun");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  EXPECT_EQ(run.contact_frames, 60);
  EXPECT_GE(max_unconstrained(run), 3) << "a flat patch leaves slide x, y and spin free";
  for (const auto& f : run.frames) {
    EXPECT_LT(z_error_m(f), 1e-4) << "the pressed depth is observable";
    // Free directions follow the priors: the estimate may lag the slide, never outrun it.
    EXPECT_LT(f.translation_error_m, 2.5e-3);
    EXPECT_LT(f.rotation_error_rad, 0.25);
  }
}

// A long thin plate (30 x 0.6 x 10 mm) pressed on its long edge from 0.4 to 0.65 mm (the press
// is observable: 0.25 mm in z), slid 1.5 mm along the edge: a strip of contact with near-vertical
// sides, whose ends lie outside the image. Along the pixel rows (0 rad) or diagonally (0.785 rad)
// the slide is reported unconstrained. At 0.3 rad the sides cross a pixel row every 3.2 pixels, and
// that staircase, fixed to the image and not to the plate, holds a pure slide at 4 % of the largest
// eigenvalue: the registrations report it constrained and read no slide, which is what the free
// direction's prior does too. Either way the estimate stays where it was and nothing runs away.
TEST(StressGeometry, LongThinEdgeSlidAlongItself) {
  const ClosedLoop loop(shape(make_box({0.015f, 0.0003f, 0.005f})));
  struct Case {
    double angle;    // to the pixel rows [rad]
    bool staircase;  // its sides' pixel staircase holds the slide
  };
  for (const auto& [angle, staircase] : {Case{0.0, false}, Case{0.3, true}, Case{0.785, false}}) {
    SCOPED_TRACE("plate at " + std::to_string(angle) + " rad to the pixel rows");
    const Eigen::Quaterniond q(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
    std::vector<SE3> poses;
    for (int f = 0; f < 60; ++f) {
      const double s = 0.0015 * f / 59.0;
      const double press = 0.0004 + 0.00025 * f / 59.0;
      poses.push_back(SE3(q, q * Eigen::Vector3d(s, 0, 0) + Eigen::Vector3d(0, 0, 0.005 - press)));
    }
    const StressRun run = loop.track(poses);
    run.print("LongThinEdgeSlidAlongItself at " + std::to_string(angle) + " rad");
    ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
    EXPECT_EQ(run.contact_frames, 60);
    if (!staircase) {
      EXPECT_GE(max_unconstrained(run), 1) << "the slide along the edge is unobservable";
    }
    for (const auto& f : run.frames) {
      EXPECT_LT(z_error_m(f), 1e-4);
      EXPECT_LT(f.translation_error_m, 2e-3);
      EXPECT_LT(f.rotation_error_rad, 0.1);
    }
  }
}

// A tilted cube corner sliding in from the image's left edge (5 mm along x over 80 frames, 1.5 mm
// up as it goes, an audit's case): the first frames see 70-90 points of a contact cut by the
// edge. Integrated as if the gel past the edge were flat, its depth was pulled to zero there and
// the contact tilted: the estimate turned away, 1.21 rad at most, lost in 73 frames (the
// audit's render through `patchgraph track`: 2.3 rad). With the image mirrored across the edge
// (DepthFromNormals::compute) the rotation stays within 0.033 rad, lost 9; the corner's visible
// part is an edge at first, whose slide is free, so the estimate lags the slide (3.65 mm at the
// end, the frames report the free direction).
TEST(StressGeometry, ACornerSlidingInFromTheImagesEdge) {
  const ClosedLoop& loop = cube_loop();
  const Eigen::Quaterniond q(0.9130250463532416, 0.3238206133320986, -0.24642006863570398,
                             -0.0283306351227727);
  std::vector<SE3> poses;
  for (int f = 0; f < 80; ++f) {
    const double z = 0.01295666 + 2.43208e-5 * f - 6.2059e-8 * f * f;
    poses.push_back(SE3(q, Eigen::Vector3d(-0.009793 + 0.005 * f / 79.0, 0, z)));
  }
  const StressRun run = loop.track(poses);
  run.print("ACornerSlidingInFromTheImagesEdge");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  EXPECT_EQ(run.contact_frames, 80);
  EXPECT_GE(run.frames[0].cloud_points, 50);
  for (std::size_t k = 0; k < run.frames.size(); ++k) {
    EXPECT_LT(run.frames[k].rotation_error_rad, 0.05) << "frame " << k;
    EXPECT_LT(run.frames[k].translation_error_m, 5e-3) << "frame " << k;
  }
  EXPECT_LE(run.lost_frames, 15);
}

// A 6 mm sphere rolled 3 mm along x (rotating about y by distance / radius), then spun 0.5 rad
// about z in place: its rotation is unobservable, its centre is not.
TEST(StressGeometry, SphereRolledAndSpun) {
  const double r = 0.006, press = 0.0008;
  const ClosedLoop loop(mesh_shape("sphere_r6mm.glb"));
  std::vector<SE3> poses;
  for (int f = 0; f < 60; ++f) {
    const double x = 0.003 * f / 59.0;
    poses.push_back(SE3(Eigen::Quaterniond(Eigen::AngleAxisd(x / r, Eigen::Vector3d::UnitY())),
                        Eigen::Vector3d(x - 0.0015, 0, r - press)));
  }
  const SE3 rolled = poses.back();
  for (int f = 1; f <= 30; ++f) {
    const Eigen::Quaterniond spin(Eigen::AngleAxisd(0.5 * f / 30.0, Eigen::Vector3d::UnitZ()));
    poses.push_back(SE3(spin * rolled.rotation(), rolled.translation()));
  }
  const StressRun run = loop.track(poses);
  run.print("SphereRolledAndSpun");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  EXPECT_GE(max_unconstrained(run), 3);
  const SE3 first = run.frames.front().estimate.T_world_object;
  for (const auto& f : run.frames) {
    EXPECT_LT(f.translation_error_m, 3e-4) << "the centre is observable";
    // The unobservable rotation keeps the initial orientation instead of wandering.
    EXPECT_LT(rotation_distance(f.estimate.T_world_object, first), 0.05);
  }
  // ... which is the rotation's error: 0.5 rad rolled, then spun 0.5 rad.
  EXPECT_GT(run.last().rotation_error_rad, 0.5);
}

// A featureless patch: a 50 mm sphere (radius 25 mm), the contact nearly flat, moved 1.1 mm
// sideways, pressed 0.2 mm throughout and pressed from 0.2 to 0.4 mm. The cap's rolls about its
// far centre are free; its slide (the centre's) is seen, barely, and tracked: 0.002 and 0.005 mm
// at most. Until the rolls were told from slivers by the contact's curvature
// (DegeneracyReport::unconstrained_twists), the factor graph was handed the slide as free: at
// constant depth the estimate lagged it by 0.93 mm at the end, with 11 frames reported lost.
TEST(StressGeometry, FeaturelessPatch) {
  const ClosedLoop loop(shape(make_uv_sphere(0.025f, 128, 256)));
  for (const double deepening : {0.0, 0.0002}) {
    SCOPED_TRACE("pressed 0.2 mm + " + std::to_string(deepening * 1e3) + " mm");
    std::vector<SE3> poses;
    for (int f = 0; f < 40; ++f) {
      const double s = f / 39.0;
      poses.push_back(SE3::Translation({0.001 * s, 0.0005 * s, 0.025 - 0.0002 - deepening * s}));
    }
    const StressRun run = loop.track(poses);
    run.print(deepening > 0 ? "FeaturelessPatch deepening" : "FeaturelessPatch");
    ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
    EXPECT_EQ(run.contact_frames, 40);
    EXPECT_GE(max_unconstrained(run), 3);
    EXPECT_EQ(run.lost_frames, 0);
    for (std::size_t k = 0; k < run.frames.size(); ++k) {
      const StressFrame& f = run.frames[k];
      EXPECT_LT(z_error_m(f), 1e-4) << "frame " << k;
      EXPECT_LT(f.translation_error_m, 0.05e-3) << "frame " << k;
    }
  }
}

// Spheres of 1, 2, 5, 10, 20 and 50 mm diameter pressed 0.3 mm and slid 1 mm. A 1 mm sphere's
// contact (about 20 pixels at 120x160) is at the edge of what the front end resolves: it may be
// seen as no contact, or give too few points to register, and must then be reported as such.
TEST(StressScale, ObjectsFrom1To50Millimetres) {
  for (double diameter_mm : {1.0, 2.0, 5.0, 10.0, 20.0, 50.0}) {
    SCOPED_TRACE("diameter " + std::to_string(diameter_mm) + " mm");
    const double r = diameter_mm * 0.5e-3;
    const ClosedLoop loop(shape(make_uv_sphere(float(r), 96, 192)));
    std::vector<SE3> poses;
    for (int f = 0; f < 30; ++f) poses.push_back(SE3::Translation({0.001 * f / 29.0, 0, r - 3e-4}));
    const StressRun run = loop.track(poses);
    ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
    int min_points = 1 << 30;
    for (const auto& f : run.frames) min_points = std::min(min_points, f.cloud_points);
    std::printf(
        "diameter %4.0f mm: contact %d/30 frames, episodes %d, >= %d points, lost %d, "
        "unconverged %d, max error %.3f mm\n",
        diameter_mm, run.contact_frames, run.episodes, min_points, run.lost_frames,
        run.unconverged_registrations, run.max_translation_error_m() * 1e3);
    if (diameter_mm >= 2.0) {
      EXPECT_EQ(run.contact_frames, 30);
      EXPECT_LT(run.max_translation_error_m(), 5e-4);
    } else {
      // Untracked frames are reported: each frame more than 0.5 mm off (the slide lost) says
      // so itself, as no contact, tracking lost or a registration that did not converge.
      EXPECT_LT(run.max_translation_error_m(), 1.5e-3);
      for (std::size_t k = 0; k < run.frames.size(); ++k) {
        const TrackerEstimate& e = run.frames[k].estimate;
        if (run.frames[k].translation_error_m <= 5e-4) continue;
        EXPECT_TRUE(!e.contact || e.tracking_lost || e.unconverged_registrations > 0 ||
                    e.rejected_registrations > 0)
            << "frame " << k << ": " << run.frames[k].translation_error_m * 1e3
            << " mm off without a report";
      }
    }
  }
}

// A ball held still on the gel, 6 mm to 1 m in radius, with the tools' pose noise (sensor poses
// 1e-5, the first pose's prior 1e-4): it must stay where it was. A large ball's roll about its far
// centre carries little rotation per slide (Lambda / R), as little as an edge's sliver, and was
// handed to the factor graph as a slide: the roll's tilt was then pinned at the registration's
// guess, the prediction, and a 0.15 m ball spun away by 15 % a frame (0.74 rad after 140 frames,
// lost from frame 80), a 1 m one from the start (1.3 rad). Its free directions are now the rolls,
// recognised by the contact's curvature (DegeneracyReport::unconstrained_twists).
TEST(StressScale, AStillBallOfAnySizeStaysStill) {
  for (const double r : {0.006, 0.15, 1.0}) {
    SCOPED_TRACE("radius " + std::to_string(r) + " m");
    const ClosedLoop loop(shape(make_uv_sphere(float(r), 192, 384)));
    const std::vector<SE3> poses(150, SE3::Translation({0, 0, r - 3e-4}));
    std::mt19937_64 rng(7);
    std::normal_distribution<double> normal;
    const auto perturbed = [&](const SE3& pose, double sigma) {
      Vector6d xi;
      for (int k = 0; k < 6; ++k) xi[k] = sigma * normal(rng);
      return pose * SE3::exp(xi);
    };
    StressHooks hooks;
    hooks.corrupt_input = [&](int, TrackerInput& in) {
      in.T_world_sensor_measured = perturbed(in.T_world_sensor_measured, 1e-5);
      in.T_world_object_prior = perturbed(in.T_world_object_prior, 1e-4);
    };
    const StressRun run = loop.track(poses, {}, hooks);
    run.print("AStillBallOfAnySizeStaysStill r=" + std::to_string(r));
    ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
    EXPECT_EQ(run.contact_frames, 150);
    EXPECT_GE(max_unconstrained(run), 3) << "the rotations are free";
    EXPECT_EQ(run.lost_frames, 0);
    for (std::size_t k = 0; k < run.frames.size(); ++k) {
      // The first pose's prior is 0.1-0.2 mm and 0.2 mrad off; the rest must not add to it.
      EXPECT_LT(run.frames[k].rotation_error_rad, 1e-3) << "frame " << k;
      EXPECT_LT(run.frames[k].translation_error_m, 0.3e-3) << "frame " << k;
    }
  }
}

// The default DIGIT (elastic gel, 2 mm maximum indentation, noise, every output) under a 6 mm
// sphere pressed from 1 um to far past the gel, up to the whole sphere behind the gel surface.
TEST(StressScale, PressesFromOneMicrometreToBeyondTheGel) {
  const SensorModel sensor = sensor_preset("digit");
  RenderSettings settings;
  settings.contact_points = true;
  const SensorRenderer renderer(sensor, {mesh_shape("sphere_r6mm.glb")}, settings);
  ContactCloudBuilder builder(sensor, ContactCloudOptions());
  for (double press : {1e-6, 1e-5, 1e-4, 1e-3, 2e-3, 3e-3, 6e-3, 12e-3, 30e-3}) {
    SCOPED_TRACE("press " + std::to_string(press * 1e3) + " mm");
    const RenderedFrame frame = renderer.render({SE3::Translation({0, 0, 0.006 - press})}, 7);
    EXPECT_TRUE(all_finite(frame.images.normal));
    EXPECT_TRUE(all_finite(frame.images.depth));
    float deepest = 0;
    for (float u : frame.images.depth.data) deepest = std::max(deepest, u);
    EXPECT_LE(deepest, sensor.gel.max_indentation_m * 1.001);
    if (press > sensor.gel.max_indentation_m && press < 0.012) {
      EXPECT_GT(frame.stats.clamped_pixels, 0) << "clamping is reported";
    }
    const ContactFrame contact = builder.build(frame.images.normal);
    std::printf(
        "[stress] press %.3f mm: %s, rendered contact %d px, clamped %d px, deepest %.3f "
        "mm; front end %s, %zu points\n",
        press * 1e3, frame.stats.contact ? "contact" : "no contact", frame.stats.contact_pixels,
        frame.stats.clamped_pixels, deepest * 1e3,
        contact.status == ContactStatus::kContact ? "contact" : "no contact",
        contact.cloud_sensor.size());
    EXPECT_TRUE(all_finite(contact.depth.depth));
    EXPECT_TRUE(all_finite(contact.cloud_sensor));
    if (press <= 1e-5) {
      EXPECT_EQ(contact.status, ContactStatus::kNoContact) << "below the mask's threshold";
    }
    if (press >= 1e-3 && press <= 3e-3) {
      EXPECT_EQ(contact.status, ContactStatus::kContact);
    }
  }
}

// A box pressed 1.5 mm into the rigid gel: its sides are parallel to the rays, so the rendered
// normals at the contact edge have n.z near 0. And normal images no renderer makes: exactly
// tangent (n.z = 0), pointing into the gel (n.z < 0), zero and non-finite normals.
TEST(StressScale, SteepContactEdges) {
  const ClosedLoop loop(shape(make_box({0.004f, 0.003f, 0.005f})));
  const ImageF normals =
      loop.normals(SE3(Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ())),
                       {0, 0, 0.005 - 0.0015}));
  ASSERT_TRUE(all_finite(normals));
  float min_nz = 1;
  for (std::size_t i = 2; i < normals.data.size(); i += 3)
    min_nz = std::min(min_nz, normals.data[i]);
  EXPECT_LT(min_nz, 0.3f) << "the case must reach steep normals";
  ContactCloudBuilder builder(loop.render_case().sensor, ContactCloudOptions());
  ContactFrame contact = builder.build(normals);
  EXPECT_GT(contact.depth.clamped_normals, 0) << "the eq. 4 guard is reported";
  EXPECT_TRUE(all_finite(contact.depth.depth));
  EXPECT_TRUE(all_finite(contact.cloud_sensor));
  EXPECT_EQ(contact.status, ContactStatus::kContact);
  std::printf(
      "[stress] steep edges: min n.z %.3f, %d normals clamped by the eq. 4 guard, %zu "
      "points\n",
      min_nz, contact.depth.clamped_normals, contact.cloud_sensor.size());

  ImageF bad = normals;
  const int w = bad.width, h = bad.height;
  const float values[][3] = {{1, 0, 0},   {0, -1, 0},       {0.3f, 0, -0.95f}, {0, 0, 0},
                             {NAN, 0, 1}, {INFINITY, 0, 0}, {0, 0, -1}};
  for (int y = h / 2 - 20; y < h / 2 + 20; ++y) {
    for (int x = w / 2 - 20; x < w / 2 + 20; ++x) {
      const float* v = values[(x + 3 * y) % 7];
      for (int k = 0; k < 3; ++k) bad.at(x, y, k) = v[k];
    }
  }
  contact = builder.build(bad);
  EXPECT_GT(contact.rejected_normals, 0);
  EXPECT_TRUE(all_finite(contact.depth.depth));
  EXPECT_TRUE(all_finite(contact.cloud_sensor));
  float largest = 0;
  for (float u : contact.depth.depth.data) largest = std::max(largest, std::abs(u));
  EXPECT_LT(largest, 0.05f) << "indentation bounded";
  std::printf("[stress] impossible normals: %d rejected, largest |indentation| %.3f mm\n",
              contact.rejected_normals, largest * 1e3);
}

}  // namespace
}  // namespace pg::stress
