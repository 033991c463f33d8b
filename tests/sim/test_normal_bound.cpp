// pg::normal_bound: the per-pixel Cramer-Rao bound of a normal read from one colour frame, against
// a Lambertian model written out here, the renderer's own no-contact image, and its invariances.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>

#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "pg/sim/normal_bound.h"
#include "pg/sim/renderer.h"

namespace pg {
namespace {

// The DIGIT, dimmed so that nothing clips (its brightest pixel about 140 levels).
SensorModel dim_digit(double exposure = 0.3) {
  SensorModel s = sensor_preset("digit");
  s.shading.exposure = exposure;
  return s;
}

// sigma sqrt(trace((J^T J)^-1)) with J written out for diffuse light alone: each light adds
// colour * exposure * (ambient + diffuse * max(0, -n.l)) * (d0 / d)^2, so a tilt of n along t
// changes it by colour * exposure * diffuse * (-t.l) * (d0 / d)^2 where the light is in front.
double lambert_bound(const SensorModel& s, const GelRays& rays, const ImageF& gel, int x, int y,
                     double sigma) {
  const int i = rays.index(x, y);
  const Eigen::Vector3d p = rays.point(i, 0.0f).cast<double>();
  const Eigen::Vector3d n(gel.at(x, y, 0), gel.at(x, y, 1), gel.at(x, y, 2));
  const Eigen::Vector3d t1 = n.unitOrthogonal(), t2 = n.cross(t1);
  Eigen::Matrix<double, 3, 2> J = Eigen::Matrix<double, 3, 2>::Zero();
  for (const PointLight& light : s.lights) {
    const Eigen::Vector3d to_light = light.position_m - p;
    const Eigen::Vector3d l = to_light.normalized();
    if (-n.dot(l) <= 0) continue;
    const double scale = 255.0 * s.shading.exposure * light.intensity * s.shading.diffuse *
                         light.position_m.squaredNorm() / to_light.squaredNorm();
    J.col(0) += scale * light.color * -t1.dot(l);
    J.col(1) += scale * light.color * -t2.dot(l);
  }
  return sigma * std::sqrt((J.transpose() * J).inverse().trace());
}

TEST(NormalBound, MatchesTheDiffuseShadingWrittenOut) {
  SensorModel s = dim_digit();
  s.shading.specular = 0;
  const NormalBound b = normal_bound(s, 7.0);
  const GelRays rays = make_gel_rays(s.camera, s.gel);
  const ImageF gel = undeformed_gel_normals(rays);
  int checked = 0;
  for (int y = 5; y < rays.height; y += 30) {
    for (int x = 5; x < rays.width; x += 25) {
      const double expected = lambert_bound(s, rays, gel, x, y, 7.0);
      ASSERT_TRUE(std::isfinite(expected)) << x << "," << y;
      EXPECT_NEAR(b.angle_rad.at(x, y), expected, 2e-3 * expected) << x << "," << y;
      ++checked;
    }
  }
  EXPECT_GE(checked, 20);
  // A few degrees on the DIGIT's gel at its own noise and exposure, dimmed here by a third.
  EXPECT_GT(b.angle_rad.at(60, 80), 0.02);
  EXPECT_LT(b.angle_rad.at(60, 80), 0.3);
}

TEST(NormalBound, ScalesWithTheNoiseAndAgainstTheExposure) {
  const NormalBound a = normal_bound(dim_digit(0.3), 7.0, 0.3, 1.0);
  const NormalBound noisier = normal_bound(dim_digit(0.3), 14.0, 0.3, 1.0);
  const NormalBound dimmer = normal_bound(dim_digit(0.15), 7.0, 0.3, 1.0);
  int finite = 0;
  for (std::size_t i = 0; i < a.angle_rad.data.size(); ++i) {
    const float v = a.angle_rad.data[i];
    if (!std::isfinite(v)) continue;
    ++finite;
    EXPECT_NEAR(noisier.angle_rad.data[i], 2 * v, 1e-4 * v) << i;
    EXPECT_NEAR(dimmer.angle_rad.data[i], 2 * v, 1e-3 * v) << i;
  }
  EXPECT_GT(finite, int(a.angle_rad.data.size() * 9 / 10));
  EXPECT_EQ(a.clipped_fraction, (std::array<double, 3>{0, 0, 0}));
}

// One light changes the three channels together: the colour moves along one line, and two tilts
// cannot be told apart anywhere. Two lights can.
TEST(NormalBound, OneLightCannotTellTwoTilts) {
  SensorModel one = dim_digit();
  one.lights.resize(1);
  const NormalBound b1 = normal_bound(one, 7.0);
  EXPECT_TRUE(std::all_of(b1.angle_rad.data.begin(), b1.angle_rad.data.end(),
                          [](float v) { return !std::isfinite(v) || v > 1.0f; }));
  SensorModel two = dim_digit();
  two.lights.resize(2);
  const NormalBound b2 = normal_bound(two, 7.0);
  const auto finite = std::count_if(b2.angle_rad.data.begin(), b2.angle_rad.data.end(),
                                    [](float v) { return v < 0.3f; });
  EXPECT_GT(finite, long(b2.angle_rad.data.size() * 9 / 10));
}

// The shading is the renderer's: its no-contact image (before it is quantised) agrees, and is
// 255 or more where the bound counts a channel clipped.
TEST(NormalBound, ClippingIsTheRenderersNoContactImages) {
  for (const double exposure : {0.3, 0.9}) {
    const SensorModel s = dim_digit(exposure);
    RenderSettings settings;
    settings.noise = false;
    const SensorRenderer renderer(s, {}, settings);
    const ImageF& bg = renderer.background_color();
    const NormalBound b = normal_bound(s, 7.0);
    for (int c = 0; c < 3; ++c) {
      float brightest = 0;
      int white = 0;
      for (std::size_t i = c; i < bg.data.size(); i += 3) {
        brightest = std::max(brightest, 255.0f * bg.data[i]);
        white += bg.data[i] >= 1.0f;
      }
      const double pixels = double(bg.width) * bg.height;
      EXPECT_NEAR(b.brightest[c], brightest, 0.05) << exposure << " " << c;
      EXPECT_NEAR(b.clipped_fraction[c], white / pixels, 3.0 / pixels) << exposure << " " << c;
    }
    if (exposure > 0.5) {
      EXPECT_GT(b.brightest[1], 300.0);
      EXPECT_GT(b.clipped_fraction[0], 0.05);
    }
  }
}

// A clipped channel tells nothing. The preset clips one channel or another over a fifth of its
// gel: there it is worse than the dimmed sensor scaled to its exposure (never better anywhere);
// over-exposed, most pixels keep one channel or none and are blind.
TEST(NormalBound, ClippedChannelsTellNothing) {
  const NormalBound b = normal_bound(sensor_preset("digit"), 7.0);
  const NormalBound dim = normal_bound(dim_digit(), 7.0);
  int compared = 0, worse = 0;
  for (std::size_t i = 0; i < b.angle_rad.data.size(); ++i) {
    const float scaled = dim.angle_rad.data[i] * 0.3f / 0.9f;
    if (!std::isfinite(scaled)) continue;
    EXPECT_GE(b.angle_rad.data[i], 0.999f * scaled) << i;
    worse += b.angle_rad.data[i] > 1.01f * scaled;
    ++compared;
  }
  EXPECT_GT(compared, int(b.angle_rad.data.size() * 9 / 10));
  const double clipped = *std::max_element(b.clipped_fraction.begin(), b.clipped_fraction.end());
  EXPECT_GT(clipped, 0.1);
  EXPECT_GE(worse, int((clipped - 0.01) * b.angle_rad.data.size()));
  const NormalBound glare = normal_bound(dim_digit(5.0), 7.0);
  const auto blind = std::count_if(glare.angle_rad.data.begin(), glare.angle_rad.data.end(),
                                   [](float v) { return !std::isfinite(v); });
  EXPECT_GT(blind, long(glare.angle_rad.data.size() / 2));
}

TEST(NormalBound, RefusesNoNoiseAndATiltOfAQuarterTurn) {
  EXPECT_THROW(normal_bound(dim_digit(), 0.0), InputError);
  EXPECT_THROW(normal_bound(dim_digit(), std::nan("")), InputError);
  EXPECT_THROW(normal_bound(dim_digit(), 7.0, M_PI / 2), InputError);
  EXPECT_THROW(normal_bound(dim_digit(), 7.0, -0.1), InputError);
}

}  // namespace
}  // namespace pg
