#include "pg/sim/shading_inversion.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "change_filter.h"
#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "pg/core/image_change.h"
#include "shading.h"

namespace pg {

namespace {

// What a colour channel tells about the shading [levels]: its value, a bound (the camera clipped
// it at 255 or 0: the shading is at least, or at most, that), or nothing (a blended frame whose
// channel, or whose reference's, is clipped).
enum class Reading : std::uint8_t { kValue, kAtLeast, kAtMost, kNothing };

float residual(Reading reading, float model, float target) {
  switch (reading) {
    case Reading::kValue:
      return model - target;
    case Reading::kAtLeast:
      return std::min(0.0f, model - target);
    case Reading::kAtMost:
      return std::max(0.0f, model - target);
    case Reading::kNothing:
      break;
  }
  return 0.0f;
}

// Pixels this far from a changed region still get their own estimate: the change test's 10 levels
// (in a 3x3 mean) are a turn of a few degrees, which a contact's rim stays below.
constexpr int kMarginPixels = 2;
// Levenberg-Marquardt per pixel on the normal's two tilts (tangents of the turn off the
// undeformed normal); the colour is nearly linear in the normal, so few iterations do.
constexpr int kIterations = 12;
constexpr float kStep = 1e-3f;  // forward difference of the tilts
constexpr float kLargestStep = 0.25f;
constexpr float kConvergedStep = 1e-4f;  // 0.1 mrad; the noise's bound is some 50 mrad
constexpr float kLargestTilt = 3.0f;     // tangent: 72 degrees
constexpr int kChunk = 4096;

}  // namespace

struct ShadingInversion::State {
  int width = 0, height = 0;
  bool blended = false;
  float gain = 1.0f;
  ChangeFilter filter{0.0};  // blended: the change, Wiener-filtered for the blend's blur
  Shader shader;
  std::vector<Eigen::Vector3f> point, gel, t1, t2;  // per pixel: undeformed gel point, normal
  std::vector<float> gel_shade;                     // the undeformed gel's shading [levels]
  ImageF gel_normals;
};

ShadingInversion::ShadingInversion(const SensorModel& sensor, bool blended)
    : state_(std::make_unique<State>()) {
  check_sensor_model(sensor, "ShadingInversion: sensor " + sensor.name);
  State& s = *state_;
  const GelRays rays = make_gel_rays(sensor.camera, sensor.gel);
  s.width = rays.width;
  s.height = rays.height;
  s.blended = blended;
  s.gain = blended ? float(sensor.shading.background_gain) : 1.0f;
  if (!(s.gain > 0)) {
    throw InputError("shading.background_gain " + std::to_string(sensor.shading.background_gain) +
                     ": a blended frame shows none of the shading's change to invert");
  }
  if (blended) s.filter = ChangeFilter(rays.blend_blur_px(sensor.shading));
  s.shader = make_shader(sensor);
  s.gel_normals = undeformed_gel_normals(rays);
  const int n = rays.width * rays.height;
  s.point.resize(n);
  s.gel.resize(n);
  s.t1.resize(n);
  s.t2.resize(n);
  for (int i = 0; i < n; ++i) {
    s.point[i] = rays.point(i, 0.0f);
    const float* g = &s.gel_normals.data[3 * std::size_t(i)];
    s.gel[i] = Eigen::Vector3f(g[0], g[1], g[2]);
    s.t1[i] = s.gel[i].unitOrthogonal();
    s.t2[i] = s.gel[i].cross(s.t1[i]);
  }
  std::vector<float> px(n), py(n), pz(n), nx(n), ny(n), nz(n);
  for (int i = 0; i < n; ++i) {
    px[i] = s.point[i].x(), py[i] = s.point[i].y(), pz[i] = s.point[i].z();
    nx[i] = s.gel[i].x(), ny[i] = s.gel[i].y(), nz[i] = s.gel[i].z();
  }
  s.gel_shade.resize(3 * std::size_t(n));
  ShadeSpan span;
  span.count = n;
  span.px = px.data(), span.py = py.data(), span.pz = pz.data();
  span.nx = nx.data(), span.ny = ny.data(), span.nz = nz.data();
  shade_span(s.shader, span, s.gel_shade.data());
  for (float& v : s.gel_shade) v *= 255.0f;
}

ShadingInversion::~ShadingInversion() = default;
ShadingInversion::ShadingInversion(ShadingInversion&&) noexcept = default;
ShadingInversion& ShadingInversion::operator=(ShadingInversion&&) noexcept = default;

ImageF ShadingInversion::normals(const ImageU8& color, const ImageU8& reference) const {
  const State& s = *state_;
  check_sensor_image("colour frame", color, s.width, s.height);
  check_sensor_image("reference image", reference, s.width, s.height);
  ImageF out = s.gel_normals;
  // The pixels to estimate: the changed regions beyond specks, and kMarginPixels around them.
  const ChangedRegions changes = changed_regions(color, reference);
  const int w = s.width, h = s.height;
  std::vector<std::uint8_t> near(std::size_t(w) * h, 0);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int r = changes.region[std::size_t(y) * w + x];
      if (r < 0 || changes.sizes[std::size_t(r)] < kSpeckPixels) continue;
      for (int yy = std::max(0, y - kMarginPixels); yy <= std::min(h - 1, y + kMarginPixels); ++yy)
        for (int xx = std::max(0, x - kMarginPixels); xx <= std::min(w - 1, x + kMarginPixels);
             ++xx)
          near[std::size_t(yy) * w + xx] = 1;
    }
  }
  std::vector<int> pixels;
  for (int i = 0; i < w * h; ++i)
    if (near[i]) pixels.push_back(i);
  // A blended frame's change at those pixels, filtered for the blend's blur and the noise.
  std::vector<float> change;
  if (s.blended) s.filter.change_at(color, reference, pixels, change);

  // Per chunk of pixels: what each channel reads, and the tilts solved so far.
  std::vector<float> target(3 * kChunk), a(kChunk), b(kChunk), mu(kChunk);
  std::vector<Reading> reading(3 * kChunk);
  // Per iteration, the pixels still moving, in structure-of-arrays form for shade_span: their
  // points, the normals of three samples (the tilts, and a step in each: a1, b1) and then of the
  // trial.
  std::vector<int> moving(kChunk);
  std::vector<float> px(kChunk), py(kChunk), pz(kChunk);
  std::vector<float> nx(3 * kChunk), ny(3 * kChunk), nz(3 * kChunk), rgb(9 * kChunk);
  std::vector<float> cost(kChunk), trial_a(kChunk), trial_b(kChunk), a1(kChunk), b1(kChunk);
  for (std::size_t start = 0; start < pixels.size(); start += kChunk) {
    const int count = int(std::min<std::size_t>(kChunk, pixels.size() - start));
    const int* idx = &pixels[start];
    for (int j = 0; j < count; ++j) {
      const int i = idx[j];
      a[j] = b[j] = 0.0f;
      mu[j] = 1e-3f;
      moving[j] = j;
      for (int c = 0; c < 3; ++c) {
        const std::size_t at = 3 * std::size_t(i) + c;
        const int seen = color.data[at], ref = reference.data[at];
        Reading& r = reading[3 * j + c];
        float& t = target[3 * j + c];
        if (!s.blended) {
          // The frame is the shading plus noise, clipped to 8 bits.
          t = float(seen);
          r = seen >= 255 ? Reading::kAtLeast : seen <= 0 ? Reading::kAtMost : Reading::kValue;
        } else if (seen > 0 && seen < 255 && ref > 0 && ref < 255) {
          // bg + gain blur(sim - sim_bg): the shading is sim_bg plus the change (filtered) over
          // the gain.
          t = s.gel_shade[at] + change[3 * (start + j) + c] / s.gain;
          r = Reading::kValue;
        } else {
          t = 0.0f;
          r = Reading::kNothing;
        }
      }
    }
    int m = count;  // moving pixels
    // Shades sample k of the m moving pixels, at tilts (ta, tb) of each (indexed by pixel j).
    auto shade = [&](int k, const float* ta, const float* tb) {
      const std::size_t o = std::size_t(k) * kChunk;
      for (int q = 0; q < m; ++q) {
        const int j = moving[q], i = idx[j];
        const Eigen::Vector3f n = (s.gel[i] + ta[j] * s.t1[i] + tb[j] * s.t2[i]).normalized();
        nx[o + q] = n.x(), ny[o + q] = n.y(), nz[o + q] = n.z();
      }
      ShadeSpan span;
      span.count = m;
      span.px = px.data(), span.py = py.data(), span.pz = pz.data();
      span.nx = &nx[o], span.ny = &ny[o], span.nz = &nz[o];
      shade_span(s.shader, span, &rgb[3 * o]);
    };
    auto residuals = [&](int k, int q, float r[3]) {
      const int j = moving[q];
      for (int c = 0; c < 3; ++c) {
        r[c] = residual(reading[3 * j + c], 255.0f * rgb[3 * (std::size_t(k) * kChunk + q) + c],
                        target[3 * j + c]);
      }
    };
    for (int it = 0; it < kIterations && m > 0; ++it) {
      for (int q = 0; q < m; ++q) {
        const int j = moving[q];
        const Eigen::Vector3f& p = s.point[idx[j]];
        px[q] = p.x(), py[q] = p.y(), pz[q] = p.z();
        a1[j] = a[j] + kStep;
        b1[j] = b[j] + kStep;
      }
      shade(0, a.data(), b.data());
      shade(1, a1.data(), b.data());
      shade(2, a.data(), b1.data());
      for (int q = 0; q < m; ++q) {
        const int j = moving[q];
        float r0[3], ra[3], rb[3];
        residuals(0, q, r0);
        residuals(1, q, ra);
        residuals(2, q, rb);
        double h00 = 0, h01 = 0, h11 = 0, g0 = 0, g1 = 0, c0 = 0;
        for (int c = 0; c < 3; ++c) {
          const double ja = (ra[c] - r0[c]) / kStep, jb = (rb[c] - r0[c]) / kStep;
          h00 += ja * ja, h01 += ja * jb, h11 += jb * jb;
          g0 += ja * r0[c], g1 += jb * r0[c];
          c0 += double(r0[c]) * r0[c];
        }
        cost[q] = float(c0);
        const double damp = mu[j] * 0.5 * (h00 + h11) + 1e-9;
        const double d00 = h00 + damp, d11 = h11 + damp, det = d00 * d11 - h01 * h01;
        double da = 0, db = 0;
        if (det > 0 && std::isfinite(det)) {
          da = -(d11 * g0 - h01 * g1) / det;
          db = -(d00 * g1 - h01 * g0) / det;
        }
        const double len = std::hypot(da, db);
        if (len > kLargestStep) da *= kLargestStep / len, db *= kLargestStep / len;
        double na = a[j] + da, nb = b[j] + db;
        const double tilt = std::hypot(na, nb);
        if (tilt > kLargestTilt) na *= kLargestTilt / tilt, nb *= kLargestTilt / tilt;
        trial_a[j] = float(na);
        trial_b[j] = float(nb);
      }
      shade(0, trial_a.data(), trial_b.data());
      // Keep a trial that lowers the cost; a pixel whose step has become negligible, or that
      // no step improves, is done.
      int still = 0;
      for (int q = 0; q < m; ++q) {
        const int j = moving[q];
        float r[3];
        residuals(0, q, r);
        const float c1 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
        bool done;
        if (c1 < cost[q]) {
          done = std::hypot(trial_a[j] - a[j], trial_b[j] - b[j]) < kConvergedStep;
          a[j] = trial_a[j], b[j] = trial_b[j];
          mu[j] = std::max(mu[j] / 3.0f, 1e-6f);
        } else {
          mu[j] *= 4.0f;
          done = mu[j] > 1e4f;
        }
        if (!done) moving[still++] = j;
      }
      m = still;
    }
    for (int j = 0; j < count; ++j) {
      const int i = idx[j];
      const Eigen::Vector3f n = (s.gel[i] + a[j] * s.t1[i] + b[j] * s.t2[i]).normalized();
      float* o = &out.data[3 * std::size_t(i)];
      o[0] = n.x(), o[1] = n.y(), o[2] = n.z();
    }
  }
  return out;
}

}  // namespace pg
