// Normals -> indentation (eq. 4 + DST Poisson): the solver against its own discrete operator,
// analytic sphere normals against the analytic indentation at both DIGIT resolutions, cropped
// against full-image integration, and bad input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "pg/core/error.h"
#include "pg/tracker/contact_cloud.h"
#include "pg/tracker/depth_from_normals.h"
#include "pg/tracker/poisson_dst.h"
#include "tracker_test_util.h"

namespace pg {
namespace {

using test::analytic_sphere_frame;

TEST(PoissonDst, FastSizesFactorIntoSmallPrimesAndAreMinimal) {
  for (int n = 1; n < 400; ++n) {
    const int m = dst_fast_size(n);
    ASSERT_GE(m, n);
    int k = m + 1;
    for (int p : {2, 3, 5, 7})
      while (k % p == 0) k /= p;
    EXPECT_EQ(k, 1) << n;
  }
  EXPECT_EQ(dst_fast_size(319), 319);
  EXPECT_EQ(dst_fast_size(320), 323);  // 324 = 2^2 3^4
  EXPECT_EQ(dst_fast_size(120), 124);  // 125 = 5^3
}

TEST(PoissonDst, SolvesItsDiscreteOperatorToFloatPrecisionAndReusesPlans) {
  for (DstBackend backend : {DstBackend::kRealFft, DstBackend::kFftwR2r}) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> uni(-1, 1);
    PoissonDstSolver solver(PoissonDstOptions{backend, false, 32});
    for (auto [nx, ny] :
         {std::pair{15, 20}, std::pair{34, 26}, std::pair{15, 20}, std::pair{1, 7}}) {
      // A random w with w = 0 outside; f = its 5-point Laplacian; the solve must give w back.
      std::vector<float> w(nx * ny);
      for (auto& v : w) v = uni(rng);
      auto at = [&](int x, int y) {
        return (x < 0 || y < 0 || x >= nx || y >= ny) ? 0.0f : w[y * nx + x];
      };
      float* f = solver.grid(nx, ny);
      for (int y = 0; y < ny; ++y) {
        for (int x = 0; x < nx; ++x) {
          f[y * nx + x] = at(x + 1, y) + at(x - 1, y) + at(x, y + 1) + at(x, y - 1) - 4 * at(x, y);
        }
      }
      solver.solve();
      double max_err = 0;
      for (int i = 0; i < nx * ny; ++i) max_err = std::max(max_err, double(std::abs(f[i] - w[i])));
      EXPECT_LT(max_err, 2e-5) << nx << " x " << ny
                               << (backend == DstBackend::kRealFft ? " real fft" : " r2r");
    }
    EXPECT_EQ(solver.plans_created(), 3);
    EXPECT_EQ(solver.cached_sizes(), 3);
  }
}

struct SphereCase {
  const char* preset;
  double press_m;
};
void PrintTo(const SphereCase& c, std::ostream* os) {
  *os << c.preset << ", press " << c.press_m * 1e3 << " mm";
}

class AnalyticSphere : public ::testing::TestWithParam<SphereCase> {};

// Eq. 4: analytic normals of a sphere (R = 6 mm) pressed into the curved DIGIT gel, integrated
// against the undeformed gel's normals, give the analytic indentation within 2% of the press
// depth in the contact core (where u > press / 2), with and without cropping, by the averaged
// integration. These normals are exact at each pixel's centre, not the renderer's central
// differences, so the parity integration (which inverts those) is off by up to twice as much at
// the rim's kink (its sub-grids have twice the spacing): within 4% here (3.1% measured).
TEST_P(AnalyticSphere, DepthWithinTwoPercentOfPressInTheCore) {
  const SphereCase sc = GetParam();
  const SensorModel sensor = sensor_preset(sc.preset);
  const double R = 0.006;
  // Centre off the middle so the contact is not symmetric about the image axes.
  const Eigen::Vector3d c(0.0015, -0.002, 0.0);
  const Eigen::Vector3d centre(c.x(), c.y(), sensor.gel.surface_z(c.x(), c.y()) + R - sc.press_m);
  const auto frame = analytic_sphere_frame(sensor, centre, R);
  for (auto [crop, integration] :
       {std::pair{true, DepthIntegration::kAveraged}, std::pair{false, DepthIntegration::kAveraged},
        std::pair{true, DepthIntegration::kParity}, std::pair{false, DepthIntegration::kParity}}) {
    const bool parity = integration == DepthIntegration::kParity;
    DepthOptions options;
    options.crop = crop;
    options.integration = integration;
    DepthFromNormals solver(sensor, options, frame.reference);
    DepthResult out;
    solver.compute(frame.normal, out);
    double max_err = 0, true_max = 0;
    int core = 0;
    for (int i = 0; i < sensor.camera.width * sensor.camera.height; ++i) {
      const double u = frame.depth.data[i];
      true_max = std::max(true_max, u);
      if (u > 0.5 * sc.press_m) {
        ++core;
        max_err = std::max(max_err, std::abs(double(out.depth.data[i]) - u));
      }
    }
    EXPECT_GT(core, 100);
    EXPECT_LT(max_err, (parity ? 0.04 : 0.02) * sc.press_m)
        << sc.preset << (crop ? " cropped" : " full") << (parity ? " parity" : " averaged")
        << ": largest core error " << max_err * 1e6 << " um for a press of " << sc.press_m * 1e6
        << " um (true max " << true_max * 1e6 << " um), " << core << " core pixels";
    if (crop) {
      EXPECT_LT(out.window.area(), long(sensor.camera.width) * sensor.camera.height / 2)
          << "the crop should cover the contact, not the image";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Resolutions, AnalyticSphere,
                         ::testing::Values(SphereCase{"digit", 0.001},
                                           SphereCase{"digit_240x320", 0.001},
                                           SphereCase{"digit_240x320", 0.0003}),
                         [](const ::testing::TestParamInfo<SphereCase>& info) {
                           return std::string(info.param.preset) + "_press" +
                                  std::to_string(int(std::lround(info.param.press_m * 1e6))) + "um";
                         });

TEST(DepthFromNormals, GelModelReferenceMatchesANoContactFrameReference) {
  // Without a reference image the sensor model's gel stands in for it; on analytic normals the
  // two agree to well under the accuracy target.
  const SensorModel sensor = sensor_preset("digit");
  const Eigen::Vector3d centre(0, 0, 0.006 - 0.001);
  const auto frame = analytic_sphere_frame(sensor, centre, 0.006);
  DepthFromNormals with_ref(sensor, DepthOptions(), frame.reference);
  DepthFromNormals with_model(sensor, DepthOptions());
  DepthResult a, b;
  with_ref.compute(frame.normal, a);
  with_model.compute(frame.normal, b);
  double max_diff = 0;
  for (std::size_t i = 0; i < a.depth.data.size(); ++i) {
    max_diff = std::max(max_diff, double(std::abs(a.depth.data[i] - b.depth.data[i])));
  }
  EXPECT_LT(max_diff, 10e-6) << "[m]";
}

// A reference a little off unit length (a network's output, say) is the same reference: the
// disturbance test compares angles. Before, one of length 0.99 flagged every pixel as disturbed
// and one of 1.01 widened the threshold to about 8 deg.
TEST(DepthFromNormals, AReferenceOffUnitLengthGivesTheSameDepth) {
  const SensorModel sensor = sensor_preset("digit");
  const auto frame = analytic_sphere_frame(sensor, {0.002, -0.001, 0.006 - 0.0008}, 0.006);
  DepthResult unit, scaled;
  DepthFromNormals(sensor, DepthOptions(), frame.reference).compute(frame.normal, unit);
  ASSERT_GT(unit.disturbed_pixels, 100);
  for (const float length : {0.99f, 1.01f}) {
    ImageF reference = frame.reference;
    for (float& v : reference.data) v *= length;
    DepthFromNormals(sensor, DepthOptions(), reference).compute(frame.normal, scaled);
    EXPECT_EQ(scaled.disturbed_pixels, unit.disturbed_pixels) << length;
    double max_diff = 0;
    for (std::size_t i = 0; i < unit.depth.data.size(); ++i) {
      max_diff = std::max(max_diff, double(std::abs(unit.depth.data[i] - scaled.depth.data[i])));
    }
    EXPECT_LT(max_diff, 1e-7) << length << " [m]";
  }
}

// A contact cut by the image's edge: the sphere (R 6 mm, 1 mm press) centred on the gel point
// the edge's middle pixel sees, so about half of it lies past the edge (each edge in turn). The
// grid's zero gradients past the edge had pulled the depth there toward the flat gel: the core's
// largest error was 70-90 % of the press. With the image mirrored across the edge the averaged
// integration is within 2 % as in the image's middle (0.5-1.5 % measured), cropped or not; the
// parity integration, whose sub-grids of every other pixel the half-pixel mirror swaps, 3.1 %
// (top, bottom) and 5.1 % (left, right), bound 6 %.
TEST(DepthFromNormals, AContactCutByTheImagesEdgeIsNotPulledFlatThere) {
  const SensorModel sensor = sensor_preset("digit");
  const double R = 0.006, press = 0.001;
  DepthFromNormals probe(sensor, DepthOptions());
  const GelRays& rays = probe.rays();
  const int W = rays.width, H = rays.height;
  const struct {
    const char* name;
    int x, y, edge;
  } edges[] = {{"left", 0, H / 2, 0},
               {"top", W / 2, 0, 1},
               {"right", W - 1, H / 2, 2},
               {"bottom", W / 2, H - 1, 3}};
  for (const auto& e : edges) {
    const Eigen::Vector3d p = rays.point(rays.index(e.x, e.y), 0.0f).cast<double>();
    const Eigen::Vector3d centre(p.x(), p.y(), sensor.gel.surface_z(p.x(), p.y()) + R - press);
    const auto frame = analytic_sphere_frame(sensor, centre, R);
    for (auto [crop, integration] : {std::pair{true, DepthIntegration::kAveraged},
                                     std::pair{false, DepthIntegration::kAveraged},
                                     std::pair{true, DepthIntegration::kParity}}) {
      const bool parity = integration == DepthIntegration::kParity;
      SCOPED_TRACE(std::string(e.name) + (crop ? " cropped" : " full") +
                   (parity ? " parity" : " averaged"));
      DepthOptions options;
      options.crop = crop;
      options.integration = integration;
      DepthFromNormals solver(sensor, options, frame.reference);
      DepthResult out;
      solver.compute(frame.normal, out, {true, true, true, true});
      EXPECT_TRUE(out.mirrored[std::size_t(e.edge)]);
      EXPECT_EQ(std::count(out.mirrored.begin(), out.mirrored.end(), true), 1)
          << "only the edge the contact reaches";
      double max_err = 0;
      int core = 0;
      for (int i = 0; i < W * H; ++i) {
        const double u = frame.depth.data[std::size_t(i)];
        if (u <= 0.5 * press) continue;
        ++core;
        max_err = std::max(max_err, std::abs(double(out.depth.data[std::size_t(i)]) - u));
      }
      EXPECT_GT(core, 100);
      EXPECT_LT(max_err, (parity ? 0.06 : 0.02) * press)
          << "largest core error " << max_err * 1e6 << " um, " << core << " core pixels";
    }
  }
}

TEST(DepthFromNormals, ReusedResultIsClearedBetweenFrames) {
  const SensorModel sensor = sensor_preset("digit");
  const auto pressed = analytic_sphere_frame(sensor, {0.003, 0.004, 0.006 - 0.001}, 0.006);
  const auto other = analytic_sphere_frame(sensor, {-0.003, -0.004, 0.006 - 0.0005}, 0.006);
  DepthFromNormals solver(sensor, DepthOptions(), pressed.reference);
  DepthResult reused, fresh;
  solver.compute(pressed.normal, reused);
  solver.compute(other.normal, reused);
  DepthFromNormals solver2(sensor, DepthOptions(), pressed.reference);
  solver2.compute(other.normal, fresh);
  EXPECT_EQ(reused.depth.data, fresh.depth.data);
  solver.compute(pressed.reference, reused);  // no contact
  EXPECT_EQ(reused.disturbed_pixels, 0);
  for (float u : reused.depth.data) ASSERT_EQ(u, 0.0f);
}

TEST(DepthBadInput, AllBackgroundFrameIsNoContact) {
  const SensorModel sensor = sensor_preset("digit");
  ContactCloudBuilder builder(sensor, ContactCloudOptions());
  const ContactFrame f = builder.build(undeformed_gel_normals(builder.rays()));
  EXPECT_EQ(f.status, ContactStatus::kNoContact);
  EXPECT_TRUE(f.cloud_sensor.empty());
  EXPECT_EQ(f.mask.pixels, 0);
  EXPECT_TRUE(f.depth.window.empty());
}

TEST(DepthBadInput, TinyContactBelowTheMinimumAreaIsNoContact) {
  const SensorModel sensor = sensor_preset("digit");
  // A 2 mm sphere pressed 0.15 mm: about 0.9 mm^2 of contact, of which ~0.2 mm^2 deeper than 0.1
  // mm.
  const auto frame = analytic_sphere_frame(sensor, {0, 0, 0.001 - 0.00015}, 0.001);
  ContactCloudOptions options;
  options.mask.min_area_m2 = 1e-6;
  ContactCloudBuilder builder(sensor, options, frame.reference);
  const ContactFrame f = builder.build(frame.normal);
  EXPECT_GT(f.mask.pixels, 0);
  EXPECT_LT(f.mask.area_m2, 1e-6);
  EXPECT_EQ(f.status, ContactStatus::kNoContact);
  EXPECT_TRUE(f.cloud_sensor.empty());
}

TEST(DepthBadInput, NanNormalsAreRejectedAndCounted) {
  const SensorModel sensor = sensor_preset("digit");
  auto frame = analytic_sphere_frame(sensor, {0, 0, 0.006 - 0.001}, 0.006);
  ContactCloudBuilder builder(sensor, test::all_contact_pixels(), frame.reference);
  const ContactFrame clean = builder.build(frame.normal);
  ASSERT_EQ(clean.status, ContactStatus::kContact);
  // Poison 25 pixels inside the contact and 5 outside (NaN, inf, zero length).
  int poisoned = 0;
  for (int k = 0; k < 25; ++k) {
    frame.normal.at(55 + k % 5, 75 + k / 5, k % 3) = k % 2 ? NAN : INFINITY;
    ++poisoned;
  }
  for (int k = 0; k < 5; ++k) {
    for (int c = 0; c < 3; ++c) frame.normal.at(2 + k, 3, c) = 0.0f;
    ++poisoned;
  }
  const ContactFrame f = builder.build(frame.normal);
  EXPECT_EQ(f.rejected_normals, poisoned);
  EXPECT_EQ(f.depth.invalid_normals, poisoned);
  EXPECT_EQ(f.status, ContactStatus::kContact);
  for (std::size_t i = 0; i < f.cloud_sensor.size(); ++i) {
    ASSERT_TRUE(f.cloud_sensor.points[i].allFinite());
    ASSERT_TRUE(f.cloud_sensor.normals[i].allFinite());
  }
  EXPECT_LE(f.cloud_sensor.size() + 25, clean.cloud_sensor.size() + 2);
  for (float u : f.depth.depth.data) ASSERT_TRUE(std::isfinite(u));
}

// Bad normals over a contact's area in a frame that shows no contact: whether the object touches
// is unknown (kUnreadable), while a few bad pixels on the untouched gel leave it kNoContact.
TEST(DepthBadInput, BadNormalsThatCouldHideAContactMakeTheFrameUnreadable) {
  const SensorModel sensor = sensor_preset("digit");
  ContactCloudOptions options;
  ContactCloudBuilder builder(sensor, options);
  const ImageF gel = undeformed_gel_normals(builder.rays());
  const double pixel_m2 = builder.rays().pixel_area_m2();
  const int smallest = int(std::ceil(options.mask.min_area_m2 / pixel_m2));
  for (const int bad : {smallest - 1, smallest}) {
    ImageF n = gel;
    for (int k = 0; k < bad; ++k) n.at(40 + k % 10, 70 + k / 10, 0) = NAN;
    const ContactFrame f = builder.build(n);
    EXPECT_EQ(f.rejected_normals, bad);
    EXPECT_EQ(f.status, bad < smallest ? ContactStatus::kNoContact : ContactStatus::kUnreadable)
        << bad << " bad pixels, " << smallest << " make the smallest contact";
    EXPECT_TRUE(f.cloud_sensor.empty());
  }
}

// A normal image left in a PNG's encoding, (n + 1) / 2, of a real press: its normals are 1.2
// long on the flat gel, and the frame is unreadable (the band of 0.5-1.5 had read it as a
// contact of 78 % of the image). A normal image 2 % off unit length reads as the unit one.
TEST(DepthBadInput, NormalsLeftInAPngsEncodingAreRejected) {
  const SensorModel sensor = sensor_preset("digit");
  const auto frame = analytic_sphere_frame(sensor, {0, 0, 0.006 - 0.0008}, 0.006);
  ContactCloudBuilder builder(sensor, ContactCloudOptions(), frame.reference);
  const ContactFrame unit = builder.build(frame.normal);
  ASSERT_EQ(unit.status, ContactStatus::kContact);
  ImageF encoded = frame.normal;
  for (float& v : encoded.data) v = 0.5f * (v + 1.0f);
  const ContactFrame f = builder.build(encoded);
  EXPECT_EQ(f.status, ContactStatus::kUnreadable);
  EXPECT_GT(f.rejected_normals, int(0.9 * double(sensor.camera.width * sensor.camera.height)));
  EXPECT_TRUE(f.cloud_sensor.empty());
  ImageF longer = frame.normal;
  for (float& v : longer.data) v *= 1.02f;
  const ContactFrame near_unit = builder.build(longer);
  EXPECT_EQ(near_unit.status, ContactStatus::kContact);
  EXPECT_EQ(near_unit.rejected_normals, 0);
  EXPECT_EQ(near_unit.cloud_sensor.size(), unit.cloud_sensor.size());
}

// A contact whose deep part has only bad normals: the row's valid neighbours (the shallow rim)
// fill its depth in (row by row, from the rim's slopes), so the mask finds a contact there, but
// no pixel of it can be back-projected. That frame is unreadable, not the end of the contact
// (kNoContact ends the episode).
TEST(DepthBadInput, AContactOfOnlyBadNormalsIsUnreadable) {
  const SensorModel sensor = sensor_preset("digit");
  auto frame = analytic_sphere_frame(sensor, {0, 0, 0.006 - 0.001}, 0.006);
  ContactCloudBuilder builder(sensor, ContactCloudOptions(), frame.reference);
  ASSERT_EQ(builder.build(frame.normal).status, ContactStatus::kContact);
  // Every pixel indented by more than 0.3 of the mask's depth threshold: the valid rim is too
  // shallow for the mask (at 0.5, 4 of its pixels reached the mask).
  const double shallow = 0.3 * MaskOptions().min_depth_m;
  int bad = 0;
  for (int y = 0; y < frame.depth.height; ++y) {
    for (int x = 0; x < frame.depth.width; ++x) {
      if (frame.depth.at(x, y) < shallow) continue;
      frame.normal.at(x, y, 0) = NAN;
      ++bad;
    }
  }
  const ContactFrame f = builder.build(frame.normal);
  EXPECT_EQ(f.rejected_normals, bad);
  ASSERT_TRUE(f.mask.contact) << "the filled-in depth should still show the contact";
  EXPECT_TRUE(f.cloud_sensor.empty());
  EXPECT_EQ(f.status, ContactStatus::kUnreadable);
}

TEST(DepthBadInput, WrongImageSizeIsAnInputError) {
  const SensorModel sensor = sensor_preset("digit");
  DepthFromNormals solver(sensor, DepthOptions());
  DepthResult out;
  EXPECT_THROW(solver.compute(ImageF(10, 10, 3), out), InputError);
  EXPECT_THROW(DepthFromNormals(sensor, DepthOptions(), ImageF(120, 160, 1)), InputError);
  // The right shape over a buffer of another size (a camera's, wrapped by hand without the
  // channels): it had been read past its end.
  ImageF short_buffer(sensor.camera.width, sensor.camera.height, 3);
  short_buffer.data.resize(short_buffer.data.size() / 3);
  try {
    solver.compute(short_buffer, out);
    ADD_FAILURE() << "read a buffer of a third of its shape";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("image holds 19200 values, not 57600"), std::string::npos)
        << e.what();
  }
  // A sensor of an image a sensor file could not give (a 0 x 0 camera had been taken, and every
  // frame read as no contact).
  SensorModel empty = sensor;
  empty.camera.width = empty.camera.height = 0;
  try {
    ContactCloudBuilder builder(empty, ContactCloudOptions());
    ADD_FAILURE() << "a 0 x 0 sensor was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("DepthFromNormals: sensor digit.width: must be in [8, 8192] px"), std::string::npos)
        << e.what();
  }
  // Options a config file could not give (a NaN threshold had read every press as no contact).
  ContactCloudOptions nan_guard;
  nan_guard.depth.min_normal_dot_ray = NAN;
  EXPECT_THROW(ContactCloudBuilder(sensor, nan_guard), InputError);
  ContactCloudOptions negative_area;
  negative_area.mask.min_area_m2 = -1;
  try {
    ContactCloudBuilder builder(sensor, negative_area);
    ADD_FAILURE() << "a negative contact area was taken";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("ContactCloudOptions: mask.min_area_m2"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace pg
