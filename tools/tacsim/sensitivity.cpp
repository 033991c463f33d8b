#include "sensitivity.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "../common/cli_main.h"
#include "../common/sensor_choice.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/sim/normal_bound.h"

namespace pg {

namespace {

// A pixel whose bound exceeds this tells next to nothing about its normal [rad] (11.5 deg).
constexpr double kBlindRad = 0.2;
constexpr int kAzimuths = 8;

struct Summary {
  double median_rad = 0, p90_rad = 0, blind_fraction = 0;
};

// Over every pixel of every map; a blind pixel counts as the largest value.
Summary summarise(const std::vector<const ImageF*>& maps) {
  std::vector<float> values;
  for (const ImageF* map : maps) values.insert(values.end(), map->data.begin(), map->data.end());
  Summary s;
  if (values.empty()) return s;
  const auto at = [&](double q) {
    const std::size_t k = std::min(values.size() - 1, std::size_t(q * double(values.size())));
    std::nth_element(values.begin(), values.begin() + long(k), values.end());
    return double(values[k]);
  };
  s.median_rad = at(0.5);
  s.p90_rad = at(0.9);
  s.blind_fraction = double(std::count_if(values.begin(), values.end(),
                                          [](float v) { return !(v <= kBlindRad); })) /
                     double(values.size());
  return s;
}

// "2.9 deg" (or "blind" above kBlindRad).
std::string angle_text(double rad) {
  if (!(rad <= kBlindRad)) return "blind";
  char text[32];
  std::snprintf(text, sizeof text, "%.2f deg", rad * 180.0 / M_PI);
  return text;
}

void print_summary(const char* what, const Summary& s) {
  std::printf("  %s: median %s, 90th percentile %s, blind (above %.1f deg) %.1f %% of pixels\n",
              what, angle_text(s.median_rad).c_str(), angle_text(s.p90_rad).c_str(),
              kBlindRad * 180.0 / M_PI, 100.0 * s.blind_fraction);
}

}  // namespace

int run_sensitivity(const SensitivityArgs& a) {
  const SensorModel sensor = chosen_sensor(a.sensor, a.sensor_file);
  const double sigma = a.sigma >= 0 ? a.sigma : sensor.noise.sigma;
  if (!(sigma > 0)) {
    throw UsageError(a.sigma >= 0 ? "--sigma: 0; a noise-free camera bounds nothing"
                                  : "the sensor's noise.sigma is 0: a noise-free camera bounds "
                                    "nothing; give --sigma, the camera's noise in levels");
  }
  if (!a.out.empty()) {
    if (lower_extension(a.out) != ".exr") {
      throw UsageError("--out " + a.out + ": the map holds radians as floats; give an .exr file");
    }
    check_image_output(a.out);
    check_output_file(a.out, {FileKind::kExr});
  }
  const double tilt = a.tilt_deg * M_PI / 180.0;
  const NormalBounds bounds(sensor);
  const NormalBound flat = bounds.compute(sigma);
  std::vector<NormalBound> tilted;
  for (int k = 0; tilt > 0 && k < kAzimuths; ++k) {
    tilted.push_back(bounds.compute(sigma, tilt, 2.0 * M_PI * k / kAzimuths));
  }
  std::printf("sensor %s: %d x %d px, camera noise sigma %.2f levels, exposure %.3g\n",
              sensor.name.c_str(), sensor.camera.width, sensor.camera.height, sigma,
              sensor.shading.exposure);
  std::printf(
      "no-contact image before clipping: brightest %.0f / %.0f / %.0f levels (R / G / B); "
      "clipped: %.1f / %.1f / %.1f %% of pixels\n",
      flat.brightest[0], flat.brightest[1], flat.brightest[2], 100 * flat.clipped_fraction[0],
      100 * flat.clipped_fraction[1], 100 * flat.clipped_fraction[2]);
  const double brightest = *std::max_element(flat.brightest.begin(), flat.brightest.end());
  if (brightest >= 255) {
    const double fit = sensor.shading.exposure * 245.0 / brightest;
    std::printf(
        "  (shading.exposure %.3g would keep it below 255, but dims every press by as much "
        "against the same noise: docs/renderer.md, \"Clipping\")\n",
        fit);
  }
  std::printf("normal bound, one frame, per pixel (Cramer-Rao through the shading, no shadows):\n");
  print_summary("undeformed gel", summarise({&flat.angle_rad}));
  std::vector<const ImageF*> maps;
  for (const NormalBound& b : tilted) maps.push_back(&b.angle_rad);
  if (maps.empty()) {
    maps.push_back(&flat.angle_rad);
  } else {
    char what[64];
    std::snprintf(what, sizeof what, "tilted %.3g deg, %d directions", a.tilt_deg, kAzimuths);
    print_summary(what, summarise(maps));
  }
  if (!a.out.empty()) {
    // Per pixel, the median over the directions (the undeformed gel's for --tilt 0); a blind
    // pixel reads pi / 2.
    ImageF map(flat.angle_rad.width, flat.angle_rad.height, 1);
    std::vector<float> v(maps.size());
    for (std::size_t i = 0; i < map.data.size(); ++i) {
      for (std::size_t k = 0; k < maps.size(); ++k) {
        v[k] = std::min(maps[k]->data[i], float(M_PI / 2));
      }
      std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
      map.data[i] = v[v.size() / 2];
    }
    write_image(a.out, map);
    std::printf("wrote %s (per pixel, the bound's median over the directions [rad])\n",
                a.out.c_str());
  }
  return kExitOk;
}

}  // namespace pg
