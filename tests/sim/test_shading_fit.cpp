// pg::ShadingFit: a sensor's lights fitted to labelled presses. Presses rendered with lights
// other than the preset's (moved, recoloured, a stronger specular) are fitted from the preset:
// the fitted model predicts their change down to the camera's noise, and the shading's inverse
// through it reads held-out presses as well as through the true lights; and its refusals.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "pg/core/error.h"
#include "pg/core/image.h"
#include "pg/sim/primitives.h"
#include "pg/sim/renderer.h"
#include "pg/sim/shading_fit.h"
#include "pg/sim/shading_inversion.h"
#include "shading_test_support.h"

namespace pg {
namespace {

using testing_support::normal_angle;
using testing_support::TexturedBackground;

constexpr double kRadius = 0.004;

std::shared_ptr<const ObjectShape> ball() {
  static const auto shape = std::make_shared<ObjectShape>(make_uv_sphere(float(kRadius), 120, 240));
  return shape;
}

// The ball pressed `press` deep at (x, y) in S [m].
SE3 ball_at(double x, double y, double press) { return SE3::Translation({x, y, kRadius - press}); }

double median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::nth_element(v.begin(), v.begin() + std::ptrdiff_t(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// The DIGIT with lights it was not built with: each moved by 1.5-3 mm, recoloured and dimmed or
// brightened, and a stronger specular share.
SensorModel other_lights() {
  SensorModel s = sensor_preset("digit");
  const Eigen::Vector3d moves[3] = {
      {0.004, -0.003, 0.002}, {-0.003, 0.004, -0.003}, {0.002, 0.005, 0.003}};
  const Eigen::Vector3d colors[3] = {{1.0, 0.3, 0.1}, {0.2, 0.9, 0.3}, {0.1, 0.35, 1.0}};
  const double intensities[3] = {0.7, 1.2, 0.9};
  for (std::size_t k = 0; k < s.lights.size(); ++k) {
    s.lights[k].position_m += moves[k];
    s.lights[k].color = colors[k];
    s.lights[k].intensity = intensities[k];
  }
  s.shading.specular = 0.4;
  return s;
}

struct Press {
  ImageU8 color;
  ImageF normals;
};

// Ball presses on a 3 x 3 grid over the gel, 0.6-1.4 mm deep, each with its own noise.
std::vector<Press> presses(const SensorRenderer& r, std::uint64_t seed) {
  std::vector<Press> out;
  int k = 0;
  for (double y : {-0.005, 0.0, 0.005})
    for (double x : {-0.003, 0.0, 0.003}) {
      const RenderedFrame f = r.render({ball_at(x, y, 0.0006 + 0.0001 * k)}, seed + k);
      out.push_back({f.images.color, f.images.normal});
      ++k;
    }
  return out;
}

// The angles [rad] between the inverse's normals and the rendered ones over the contact pixels
// of each press.
std::vector<double> inverse_angles(const ShadingInversion& inversion, const std::vector<Press>& ps,
                                   const ImageU8& reference, const ImageF& undeformed) {
  std::vector<double> out;
  for (const Press& p : ps) {
    const ImageF n = inversion.normals(p.color, reference);
    for (std::size_t i = 0; i < n.data.size() / 3; ++i)
      if (normal_angle(p.normals, undeformed, i) > 0.05)
        out.push_back(normal_angle(n, p.normals, i));
  }
  return out;
}

struct Outcome {
  ShadingFitResult fit;
  int progress_calls = 0;
  // Median angle [rad] of the inverse's normals on held-out noise-free presses, read through the
  // true lights, the fitted ones and the preset's.
  double true_lights = 0, fitted = 0, preset = 0;
};

// Fits the preset's lights to nine noisy presses of other_lights(), rendered on the synthetic
// background or blended onto a textured one.
Outcome fit_other_lights(bool blended) {
  const SensorModel truth = other_lights();
  const SensorModel start = sensor_preset("digit");
  const TexturedBackground bg(truth);
  RenderSettings settings;
  if (blended) settings.background = bg.path;
  const SensorRenderer noisy(truth, {ball()}, settings);
  settings.noise = false;
  const SensorRenderer quiet(truth, {ball()}, settings);
  const RenderedFrame untouched = quiet.render({ball_at(0, 0, -0.01)}, 0);
  const ImageU8& reference = untouched.images.color;
  const ImageF& undeformed = untouched.images.normal;

  ShadingFit fit(start, blended);
  for (const Press& p : presses(noisy, 1)) fit.add_frame(p.color, reference, p.normals);
  Outcome out;
  out.fit = fit.solve([&](int, double rms) {
    ++out.progress_calls;
    EXPECT_TRUE(std::isfinite(rms));
  });
  const std::vector<Press> held_out = presses(quiet, 100);
  auto read = [&](const SensorModel& s) {
    return median(inverse_angles(ShadingInversion(s, blended), held_out, reference, undeformed));
  };
  out.true_lights = read(truth);
  out.fitted = read(out.fit.sensor);
  out.preset = read(start);
  std::printf(
      "%s: rms %.2f -> %.2f levels in %d iterations; the inverse's median: true lights "
      "%.4f, fitted %.4f, preset %.4f rad\n",
      blended ? "blended" : "synthetic", out.fit.rms_start_levels, out.fit.rms_levels,
      out.fit.iterations, out.true_lights, out.fitted, out.preset);
  // The fitted sensor is one a sensor file may hold.
  EXPECT_NO_THROW(sensor_from_json(sensor_to_json(out.fit.sensor), "fitted"));
  return out;
}

TEST(ShadingFit, FitsOtherLightsDownToTheCamerasNoise) {
  const Outcome o = fit_other_lights(false);
  EXPECT_EQ(o.progress_calls, o.fit.iterations);
  EXPECT_TRUE(o.fit.converged);
  EXPECT_GT(o.fit.pixels, 5000u);
  // The frames carry the camera's noise, sigma 7 levels (6.4 after clipping); the preset's
  // lights miss them by far more.
  EXPECT_LT(o.fit.rms_levels, 7.5);
  EXPECT_GT(o.fit.rms_start_levels, 5 * o.fit.rms_levels);
  // Measured: 0.0106 rad through the fitted lights, 0.0136 through the true ones (the fit also
  // takes in the shading's offset from the undeformed gel's points, which the inverse shades at),
  // 0.31 through the preset's.
  EXPECT_LT(o.fitted, 1.2 * o.true_lights);
  EXPECT_GT(o.preset, 5 * o.true_lights);
}

TEST(ShadingFit, FitsTheChangeOfFramesBlendedOntoARealBackground) {
  const Outcome o = fit_other_lights(true);
  EXPECT_TRUE(o.fit.converged);
  // The change is fitted as the inverse reads it, through the Wiener filter for the blend's blur
  // (pg::ChangeFilter), which cuts the noise the blur left unmatched: measured 14.3 -> 4.2 levels
  // (15.6 -> 7.6 with the change as it is).
  EXPECT_LT(o.fit.rms_levels, 6.0);
  EXPECT_GT(o.fit.rms_start_levels, 1.5 * o.fit.rms_levels);
  // The blur itself, which neither the fit nor the inverse models, costs the fitted lights a
  // little: measured 0.026 rad against the true lights' 0.020 (0.030 against 0.023 unfiltered;
  // without the blur 0.0069 against 0.0083), the preset's 0.13.
  EXPECT_LT(o.fitted, 1.5 * o.true_lights);
  EXPECT_GT(o.preset, 3 * o.true_lights);
}

// Frames no shading makes (white, black, random colours) under a ball's labels, and sensors
// that tell little (one light, a light off) or of another size (the GelSight Mini's 240x320):
// the fit ends with finite lights that a sensor file may hold, never NaN.
TEST(ShadingFit, AnyFramesGiveFiniteLightsASensorFileHolds) {
  SensorModel one_light = sensor_preset("digit");
  one_light.lights.resize(1);
  SensorModel dark_light = sensor_preset("digit");
  dark_light.lights[1].intensity = 0;
  std::mt19937 rng(5);
  for (const SensorModel& sensor :
       {sensor_preset("digit"), one_light, dark_light, sensor_preset("gelsight_mini")}) {
    RenderSettings settings;
    settings.noise = false;
    const SensorRenderer r(sensor, {ball()}, settings);
    const RenderedFrame untouched = r.render({ball_at(0, 0, -0.01)}, 0);
    const RenderedFrame pressed = r.render({ball_at(0.001, 0, 0.001)}, 0);
    ImageU8 white = pressed.images.color, black = white, random = white;
    std::fill(white.data.begin(), white.data.end(), std::uint8_t(255));
    std::fill(black.data.begin(), black.data.end(), std::uint8_t(0));
    for (auto& v : random.data) v = std::uint8_t(rng() & 255u);
    for (bool blended : {false, true}) {
      for (const ImageU8* frame : {&white, &black, &random}) {
        ShadingFitOptions options;
        options.max_iterations = 15;
        ShadingFit fit(sensor, blended, options);
        ASSERT_GT(fit.add_frame(*frame, untouched.images.color, pressed.images.normal), 50u);
        const ShadingFitResult result = fit.solve();
        EXPECT_TRUE(std::isfinite(result.rms_levels) && std::isfinite(result.rms_start_levels));
        EXPECT_LE(result.rms_levels, result.rms_start_levels + 1e-9);
        for (const PointLight& l : result.sensor.lights) {
          ASSERT_TRUE(l.position_m.allFinite() && l.color.allFinite() && std::isfinite(l.intensity))
              << sensor.name;
        }
        try {
          sensor_from_json(sensor_to_json(result.sensor), "fitted");
        } catch (const InputError& e) {
          ADD_FAILURE() << sensor.name << (blended ? " blended: " : ": ") << e.what();
        }
      }
    }
  }
}

TEST(ShadingFit, RefusesFramesItCannotFit) {
  const SensorModel sensor = sensor_preset("digit");
  ShadingFit fit(sensor, false);
  const SensorRenderer r(sensor, {ball()}, RenderSettings{});
  const RenderedFrame untouched = r.render({ball_at(0, 0, -0.01)}, 0);
  // No contact: nothing added, and nothing to solve.
  EXPECT_EQ(fit.add_frame(untouched.images.color, untouched.images.color, untouched.images.normal),
            0u);
  EXPECT_THROW(fit.solve(), InputError);
  const ImageU8 small(sensor.camera.width / 2, sensor.camera.height / 2, 3);
  const ImageF small_normals(sensor.camera.width / 2, sensor.camera.height / 2, 3);
  EXPECT_THROW(fit.add_frame(small, untouched.images.color, untouched.images.normal), InputError);
  EXPECT_THROW(fit.add_frame(untouched.images.color, small, untouched.images.normal), InputError);
  EXPECT_THROW(fit.add_frame(untouched.images.color, untouched.images.color, small_normals),
               InputError);
  SensorModel no_gain = sensor;
  no_gain.shading.background_gain = 0;
  EXPECT_THROW(ShadingFit(no_gain, true), InputError);
  SensorModel dark = sensor;
  dark.lights.clear();
  EXPECT_THROW(ShadingFit(dark, false), InputError);
  // Labels that are not normals (NaN, zero) are skipped, not fitted.
  const RenderedFrame pressed = r.render({ball_at(0, 0, 0.001)}, 0);
  ImageF broken = pressed.images.normal;
  std::fill(broken.data.begin(), broken.data.begin() + std::ptrdiff_t(broken.data.size() / 2), NAN);
  std::fill(broken.data.begin() + std::ptrdiff_t(broken.data.size() / 2), broken.data.end(), 0.0f);
  EXPECT_EQ(fit.add_frame(pressed.images.color, untouched.images.color, broken), 0u);
}

}  // namespace
}  // namespace pg
