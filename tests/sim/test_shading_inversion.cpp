// pg::ShadingInversion: normals read back from the renderer's colour frames by inverting its
// shading, against the frames' ground-truth normals, with and without the camera's noise, on the
// synthetic and on a real-style blended background; and its refusals.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <random>
#include <vector>

#include "change_filter.h"
#include "pg/core/error.h"
#include "pg/core/gel_elastic.h"
#include "pg/core/gel_rays.h"
#include "pg/core/image.h"
#include "pg/sim/normal_bound.h"
#include "pg/sim/primitives.h"
#include "pg/sim/renderer.h"
#include "pg/sim/shading_inversion.h"
#include "shading_test_support.h"

namespace pg {
namespace {

using testing_support::normal_angle;
using testing_support::TexturedBackground;

constexpr double kRadius = 0.006;

std::shared_ptr<const ObjectShape> sphere_shape() {
  static const auto shape = std::make_shared<ObjectShape>(make_uv_sphere(float(kRadius), 180, 360));
  return shape;
}

SE3 pressed_sphere(double press = 0.001, double cx = 0.0005) {
  return SE3::Translation({cx, 0.0, kRadius - press});
}

// The angles [rad] between the estimate and the rendered normals over the pixels whose rendered
// normal turns more than 0.05 rad from the undeformed gel's (the contact).
std::vector<double> contact_angles(const ImageF& estimate, const ImageF& truth,
                                   const ImageF& undeformed) {
  std::vector<double> out;
  for (std::size_t i = 0; i < truth.data.size() / 3; ++i) {
    if (normal_angle(truth, undeformed, i) > 0.05) out.push_back(normal_angle(estimate, truth, i));
  }
  return out;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  const std::size_t k = std::min(v.size() - 1, std::size_t(q * double(v.size())));
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(k), v.end());
  return v[k];
}

RenderSettings settings(bool noise) {
  RenderSettings s;
  s.noise = noise;
  return s;
}

ImageU8 reference_of(const SensorRenderer& r) {
  return r.render({pressed_sphere(-0.01)}, 0).images.color;  // no contact, no noise
}

TEST(ShadingInversion, ReadsTheNormalsOfANoiseFreeRender) {
  const SensorModel sensor = sensor_preset("digit");  // exposure 0.9: some channels clip
  const SensorRenderer r(sensor, {sphere_shape()}, settings(false));
  const RenderedFrame f = r.render({pressed_sphere()}, 0);
  const ShadingInversion inversion(sensor, false);
  const ImageF n = inversion.normals(f.images.color, reference_of(r));
  const ImageF undeformed = r.render({pressed_sphere(-0.01)}, 0).images.normal;
  const std::vector<double> angles = contact_angles(n, f.images.normal, undeformed);
  ASSERT_GT(angles.size(), 300u);
  // Left: the colours' rounding to 8 bits, and the shading taken at the undeformed gel, not the
  // indented (up to 1 mm nearer the lights).
  EXPECT_LT(quantile(angles, 0.5), 0.01);
  EXPECT_LT(quantile(angles, 0.9), 0.03);
  // Every normal is a unit vector; pixels far from the contact keep the undeformed normal.
  for (std::size_t i = 0; i < n.data.size() / 3; ++i) {
    const double norm = std::sqrt(double(n.data[3 * i]) * n.data[3 * i] +
                                  double(n.data[3 * i + 1]) * n.data[3 * i + 1] +
                                  double(n.data[3 * i + 2]) * n.data[3 * i + 2]);
    ASSERT_NEAR(norm, 1.0, 1e-4) << i;
  }
  EXPECT_LT(normal_angle(n, undeformed, 0), 1e-3);  // the renderer builds them from its own grid
}

TEST(ShadingInversion, WithTheCamerasNoiseItsErrorIsNearTheBound) {
  const SensorModel sensor = sensor_preset("digit");
  const SensorRenderer r(sensor, {sphere_shape()}, settings(true));
  const SensorRenderer quiet(sensor, {sphere_shape()}, settings(false));
  const ShadingInversion inversion(sensor, false);
  const ImageU8 reference = reference_of(quiet);
  const ImageF undeformed = quiet.render({pressed_sphere(-0.01)}, 0).images.normal;
  std::vector<double> angles;
  for (int seed = 1; seed <= 4; ++seed) {
    const RenderedFrame f = r.render({pressed_sphere()}, std::uint64_t(seed));
    const std::vector<double> a =
        contact_angles(inversion.normals(f.images.color, reference), f.images.normal, undeformed);
    angles.insert(angles.end(), a.begin(), a.end());
  }
  // The Cramer-Rao bound of the sensor's noise (sigma 7) at a 20 degree tilt, median over the
  // image: what an unbiased per-pixel estimate can reach.
  const NormalBound bound = normal_bound(sensor, sensor.noise.sigma, 0.35, 0.0);
  std::vector<double> b(bound.angle_rad.data.begin(), bound.angle_rad.data.end());
  const double median_bound = quantile(b, 0.5);
  ASSERT_GT(median_bound, 0.03);
  EXPECT_LT(quantile(angles, 0.5), 1.5 * median_bound);
  EXPECT_GT(quantile(angles, 0.5), 0.3 * median_bound);
}

TEST(ShadingInversion, ReadsFramesBlendedOntoARealBackground) {
  const SensorModel sensor = sensor_preset("digit");
  const TexturedBackground bg(sensor);
  RenderSettings s = settings(false);
  s.background = bg.path;
  const SensorRenderer r(sensor, {sphere_shape()}, s);
  const RenderedFrame f = r.render({pressed_sphere()}, 0);
  const ImageU8 reference = reference_of(r);
  const ImageF undeformed = r.render({pressed_sphere(-0.01)}, 0).images.normal;
  const std::vector<double> blended =
      contact_angles(ShadingInversion(sensor, true).normals(f.images.color, reference),
                     f.images.normal, undeformed);
  // Read as the shading itself, the frame's change is half what the normals make.
  const std::vector<double> unblended =
      contact_angles(ShadingInversion(sensor, false).normals(f.images.color, reference),
                     f.images.normal, undeformed);
  ASSERT_GT(blended.size(), 300u);
  EXPECT_LT(quantile(blended, 0.5), 0.03);
  EXPECT_GT(quantile(unblended, 0.5), 2 * quantile(blended, 0.5));
}

// The blend blurs the shading's change by 0.2 mm (1.26 px) and the camera adds its noise after;
// read pixel by pixel as it is, the noise the blur left no signal beside (halved by the blend's
// gain in the change) is read into every normal. The inverse reads the change through the Wiener
// filter for that blur (pg::ChangeFilter); told of no blur, it reads the frame as it is.
TEST(ShadingInversion, ReadsABlendedChangeThroughTheBlursWienerFilter) {
  const SensorModel sensor = sensor_preset("digit");
  const TexturedBackground bg(sensor);
  RenderSettings s = settings(true);
  s.background = bg.path;
  RenderSettings quiet_settings = s;
  quiet_settings.noise = false;
  const auto cube = std::make_shared<ObjectShape>(make_box({0.004f, 0.004f, 0.004f}));
  const SE3 corner =
      SE3(quaternion_from_rpy({0.6, 0.5, 0.3}), Eigen::Vector3d(0.001, -0.002, 0.0052));
  SensorModel unaware = sensor;
  unaware.shading.background_blur_m = 0.0;
  const ShadingInversion filtered(sensor, true), as_is(unaware, true);
  for (const bool is_cube : {false, true}) {
    const auto shape = is_cube ? cube : sphere_shape();
    const SE3 pose = is_cube ? corner : pressed_sphere();
    const SensorRenderer r(sensor, {shape}, s), quiet(sensor, {shape}, quiet_settings);
    const ImageU8 reference = quiet.render({pressed_sphere(-0.02)}, 0).images.color;
    const ImageF undeformed = quiet.render({pressed_sphere(-0.02)}, 0).images.normal;
    std::vector<double> with, without;
    for (int seed = 1; seed <= 3; ++seed) {
      const RenderedFrame f = r.render({pose}, std::uint64_t(seed));
      const std::vector<double> a =
          contact_angles(filtered.normals(f.images.color, reference), f.images.normal, undeformed);
      const std::vector<double> b =
          contact_angles(as_is.normals(f.images.color, reference), f.images.normal, undeformed);
      with.insert(with.end(), a.begin(), a.end());
      without.insert(without.end(), b.begin(), b.end());
    }
    ASSERT_GT(with.size(), 300u);
    std::printf(
        "%s: contact angle median %.4f, 90th percentile %.4f rad; unfiltered %.4f, "
        "%.4f\n",
        is_cube ? "cube corner" : "sphere", quantile(with, 0.5), quantile(with, 0.9),
        quantile(without, 0.5), quantile(without, 0.9));
    // Measured: the sphere 0.042 / 0.088 against 0.083 / 0.169 rad, the corner 0.083 / 0.25
    // against 0.136 / 0.32.
    EXPECT_LT(quantile(with, 0.5), 0.75 * quantile(without, 0.5));
    EXPECT_LT(quantile(with, 0.9), 0.9 * quantile(without, 0.9));
  }
}

// The filter itself: a uniform change passes as it is, also at the image's edges (mirrored); the
// camera's noise on a blurred step is cut to a fraction while the step stays; no blur leaves the
// change alone.
TEST(ChangeFilter, KeepsWhatTheBlurLeftAndCutsTheNoise) {
  const SensorModel sensor = sensor_preset("digit");
  const double blur_px = make_gel_rays(sensor.camera, sensor.gel).blend_blur_px(sensor.shading);
  ASSERT_NEAR(blur_px, 1.26, 0.01);
  const ChangeFilter filter(blur_px);
  ASSERT_TRUE(filter.active());
  std::printf("kernel radius %d px\n", filter.radius());
  EXPECT_GE(filter.radius(), 3);
  EXPECT_LE(filter.radius(), 10);
  const int w = 40, h = 30;
  ImageU8 reference(w, h, 3), flat(w, h, 3);
  std::fill(reference.data.begin(), reference.data.end(), std::uint8_t(100));
  std::fill(flat.data.begin(), flat.data.end(), std::uint8_t(130));
  std::vector<int> all(w * h);
  std::iota(all.begin(), all.end(), 0);
  std::vector<float> change;
  filter.change_at(flat, reference, all, change);
  for (float v : change) ASSERT_NEAR(v, 30.0f, 1e-3f);  // the corners' pixels too
  // A step of 60 levels at x = 20, blurred as the renderer blurs it, plus noise of sigma 7.
  const GaussianKernel g = gaussian_kernel(blur_px);
  std::vector<double> step(w);
  for (int x = 0; x < w; ++x)
    for (int d = -g.radius(); d <= g.radius(); ++d)
      step[x] += g.weights[std::size_t(std::abs(d))] * (x + d >= 20 ? 60.0 : 0.0);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 7.0);
  ImageU8 noisy(w, h, 3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      for (int c = 0; c < 3; ++c)
        noisy.at(x, y, c) =
            std::uint8_t(std::clamp(std::lround(100 + step[x] + noise(rng)), 0L, 255L));
  filter.change_at(noisy, reference, all, change);
  double before = 0, after = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = 3 * std::size_t(y * w + x);
      before += std::pow(noisy.data[i] - 100.0 - step[x], 2);
      after += std::pow(change[i] - step[x], 2);
    }
  before = std::sqrt(before / (w * h)), after = std::sqrt(after / (w * h));
  std::printf("blurred step with noise: RMS error %.2f levels as it is, %.2f filtered\n", before,
              after);
  EXPECT_LT(after, 0.6 * before);
  const ChangeFilter none(0.0);
  EXPECT_FALSE(none.active());
  none.change_at(noisy, reference, all, change);
  for (std::size_t j = 0; j < all.size(); ++j)
    ASSERT_EQ(change[3 * j], float(noisy.data[3 * j]) - 100.0f);
}

TEST(ShadingInversion, AFrameWithoutChangeIsTheUndeformedGelAndWrongSizesAreRefused) {
  const SensorModel sensor = sensor_preset("digit");
  const SensorRenderer r(sensor, {sphere_shape()}, settings(false));
  const ImageU8 reference = reference_of(r);
  const ImageF undeformed = r.render({pressed_sphere(-0.01)}, 0).images.normal;
  const ShadingInversion inversion(sensor, false);
  const ImageF n = inversion.normals(reference, reference);
  ASSERT_EQ(n.data.size(), undeformed.data.size());
  double worst = 0;
  for (std::size_t i = 0; i < n.data.size() / 3; ++i)
    worst = std::max(worst, normal_angle(n, undeformed, i));
  EXPECT_LT(worst, 1e-3);
  const ImageU8 small(sensor.camera.width / 2, sensor.camera.height / 2, 3);
  EXPECT_THROW(inversion.normals(small, reference), InputError);
  EXPECT_THROW(inversion.normals(reference, small), InputError);
  const ImageU8 gray(sensor.camera.width, sensor.camera.height, 1);
  EXPECT_THROW(inversion.normals(gray, reference), InputError);
  SensorModel no_gain = sensor;
  no_gain.shading.background_gain = 0;
  EXPECT_THROW(ShadingInversion(no_gain, true), InputError);
  EXPECT_NO_THROW(ShadingInversion(no_gain, false));
}

// Frames no shading makes (white, black, random colours) and sensors whose shading tells little
// (one light, a light off, over-exposed, nearly dark) give unit normals within the largest tilt,
// never NaN.
TEST(ShadingInversion, AnyFrameAndSensorGiveUnitNormals) {
  SensorModel one_light = sensor_preset("digit");
  one_light.lights.resize(1);
  SensorModel dark_light = sensor_preset("digit");
  dark_light.lights[1].intensity = 0;
  SensorModel glaring = sensor_preset("digit");
  glaring.shading.exposure = 20;
  SensorModel dim = sensor_preset("digit");
  dim.shading.exposure = 1e-3;
  // The blend's blur at the largest a sensor file holds (1 cm: the change's filter cut at its
  // largest reach), and one too small to blur.
  SensorModel blurry = sensor_preset("digit"), sharp = sensor_preset("digit");
  blurry.shading.background_blur_m = 0.01;
  sharp.shading.background_blur_m = 1e-7;
  std::mt19937 rng(3);
  for (const SensorModel& sensor :
       {sensor_preset("digit"), one_light, dark_light, glaring, dim, blurry, sharp}) {
    const SensorRenderer r(sensor, {sphere_shape()}, settings(false));
    const ImageU8 reference = reference_of(r);
    const ImageU8 pressed = r.render({pressed_sphere(0.0015)}, 0).images.color;
    ImageU8 white = reference, black = reference, random = reference;
    std::fill(white.data.begin(), white.data.end(), std::uint8_t(255));
    std::fill(black.data.begin(), black.data.end(), std::uint8_t(0));
    for (auto& v : random.data) v = std::uint8_t(rng() & 255u);
    for (bool blended : {false, true}) {
      const ShadingInversion inversion(sensor, blended);
      const ImageF undeformed = inversion.normals(reference, reference);
      for (const ImageU8* frame : std::vector<const ImageU8*>{&pressed, &white, &black, &random}) {
        const ImageF n = inversion.normals(*frame, reference);
        ASSERT_EQ(n.data.size(), 3 * std::size_t(sensor.camera.width) * sensor.camera.height);
        for (std::size_t i = 0; i < n.data.size() / 3; ++i) {
          const double x = n.data[3 * i], y = n.data[3 * i + 1], z = n.data[3 * i + 2];
          ASSERT_NEAR(x * x + y * y + z * z, 1.0, 1e-4) << i;
          // At most atan(3), 72 degrees, from the undeformed gel's normal.
          ASSERT_LT(normal_angle(n, undeformed, i), std::atan(3.0) + 1e-3) << i;
        }
      }
    }
  }
}

}  // namespace
}  // namespace pg
