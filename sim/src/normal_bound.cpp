#include "pg/sim/normal_bound.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "shading.h"

namespace pg {

namespace {

// A channel value [levels] that the camera's 8 bits do not clip.
bool unclipped(float value) { return value > 0.0f && value < 255.0f; }

}  // namespace

struct NormalBounds::State {
  GelRays rays;
  ImageF gel;  // the undeformed gel's normals
  Shader shader;
};

NormalBounds::NormalBounds(const SensorModel& sensor) : state_(std::make_unique<State>()) {
  check_sensor_model(sensor, "NormalBounds: sensor " + sensor.name);  // fx = 0 had read +inf
  state_->rays = make_gel_rays(sensor.camera, sensor.gel);
  state_->gel = undeformed_gel_normals(state_->rays);
  state_->shader = make_shader(sensor);
}

NormalBounds::~NormalBounds() = default;

NormalBound NormalBounds::compute(double sigma, double tilt_rad, double azimuth_rad) const {
  if (!(sigma > 0) || !std::isfinite(sigma)) {
    throw InputError("camera noise sigma " + std::to_string(sigma) +
                     ": a bound needs a positive, finite noise (a noise-free camera bounds "
                     "nothing)");
  }
  if (!(tilt_rad >= 0 && tilt_rad < M_PI / 2)) {
    throw InputError("tilt " + std::to_string(tilt_rad) + " rad: must lie in [0, pi / 2)");
  }
  const GelRays& rays = state_->rays;
  const ImageF& gel = state_->gel;
  const Shader& shader = state_->shader;
  const int n = rays.width * rays.height;
  // The tilt turns every normal about the same in-plane axis, perpendicular to the azimuth.
  const Eigen::AngleAxisf turn(float(tilt_rad),
                               Eigen::Vector3f(-std::sin(azimuth_rad), std::cos(azimuth_rad), 0));
  // Five normals per pixel: the evaluated one and a small step either way along two tangents,
  // for central differences of the colour. In chunks of pixels, so that a large image needs
  // little memory.
  constexpr int kSamples = 5, kChunk = 1 << 14;
  constexpr float kStep = 1e-3f;  // [rad]; the shading is smooth, the step's error ~1e-6
  NormalBound out;
  out.angle_rad = ImageF(rays.width, rays.height, 1);
  std::array<long, 3> clipped{};
  std::vector<float> px(kChunk), py(kChunk), pz(kChunk);
  std::vector<std::vector<float>> nx(kSamples, std::vector<float>(kChunk)),
      ny(kSamples, std::vector<float>(kChunk)), nz(kSamples, std::vector<float>(kChunk)),
      rgb(kSamples, std::vector<float>(3 * kChunk));
  for (int start = 0; start < n; start += kChunk) {
    const int count = std::min(kChunk, n - start);
    for (int j = 0; j < count; ++j) {
      const int i = start + j;
      const Eigen::Vector3f p = rays.point(i, 0.0f);
      px[j] = p.x();
      py[j] = p.y();
      pz[j] = p.z();
      const Eigen::Vector3f normal =
          turn * Eigen::Vector3f(gel.data[3 * i], gel.data[3 * i + 1], gel.data[3 * i + 2]);
      const Eigen::Vector3f t1 = normal.unitOrthogonal();
      const Eigen::Vector3f t2 = normal.cross(t1);
      const Eigen::Vector3f samples[kSamples] = {
          normal, (normal + kStep * t1).normalized(), (normal - kStep * t1).normalized(),
          (normal + kStep * t2).normalized(), (normal - kStep * t2).normalized()};
      for (int k = 0; k < kSamples; ++k) {
        nx[k][j] = samples[k].x();
        ny[k][j] = samples[k].y();
        nz[k][j] = samples[k].z();
      }
    }
    for (int k = 0; k < kSamples; ++k) {
      ShadeSpan span;
      span.count = count;
      span.px = px.data();
      span.py = py.data();
      span.pz = pz.data();
      span.nx = nx[k].data();
      span.ny = ny[k].data();
      span.nz = nz[k].data();
      shade_span(shader, span, rgb[k].data());
    }
    for (int j = 0; j < count; ++j) {
      // J^T J over the channels the camera does not clip, in levels^2 / rad^2.
      double a = 0, b = 0, c = 0;
      for (int ch = 0; ch < 3; ++ch) {
        const std::size_t at = 3 * std::size_t(j) + ch;
        const float value = 255.0f * rgb[0][at];
        out.brightest[ch] = std::max(out.brightest[ch], double(value));
        if (!unclipped(value)) {
          ++clipped[ch];
          continue;
        }
        const double d1 = 255.0 * (double(rgb[1][at]) - rgb[2][at]) / (2.0 * kStep);
        const double d2 = 255.0 * (double(rgb[3][at]) - rgb[4][at]) / (2.0 * kStep);
        a += d1 * d1;
        b += d1 * d2;
        c += d2 * d2;
      }
      // trace of the inverse of [[a, b], [b, c]]; blind where the determinant is lost in
      // rounding.
      const double det = a * c - b * b;
      out.angle_rad.data[start + j] = det > 1e-9 * (a + c) * (a + c)
                                          ? float(sigma * std::sqrt((a + c) / det))
                                          : std::numeric_limits<float>::infinity();
    }
  }
  for (int ch = 0; ch < 3; ++ch) out.clipped_fraction[ch] = double(clipped[ch]) / double(n);
  return out;
}

NormalBound normal_bound(const SensorModel& sensor, double sigma, double tilt_rad,
                         double azimuth_rad) {
  return NormalBounds(sensor).compute(sigma, tilt_rad, azimuth_rad);
}

}  // namespace pg
