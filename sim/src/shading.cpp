#include "shading.h"

#include <algorithm>
#include <cmath>

namespace pg {

std::uint64_t splitmix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

Shader make_shader(const SensorModel& sensor) {
  Shader s;
  s.model = sensor.shading;
  s.camera = Eigen::Vector3f(0, 0, float(-sensor.camera.distance_m));
  for (const auto& l : sensor.lights) {
    ShadingLight sl;
    sl.position = l.position_m.cast<float>();
    sl.color = (l.color * l.intensity * sensor.shading.exposure).cast<float>();
    sl.d0_sq = std::max(1e-12f, sl.position.squaredNorm());
    s.lights.push_back(sl);
  }
  return s;
}

namespace {

inline float power(float x, int n) {
  float r = 1.0f;
  while (n > 0) {
    if (n & 1) r *= x;
    x *= x;
    n >>= 1;
  }
  return r;
}

}  // namespace

Eigen::Vector3f shade(const Shader& shader, const Eigen::Vector3f& p, const Eigen::Vector3f& n,
                      const float* visibility) {
  const ShadingModel& m = shader.model;
  const Eigen::Vector3f n_in = -n;  // the coating faces the camera and the lights
  const Eigen::Vector3f to_camera = (shader.camera - p).normalized();
  Eigen::Vector3f rgb = Eigen::Vector3f::Zero();
  for (std::size_t k = 0; k < shader.lights.size(); ++k) {
    const ShadingLight& light = shader.lights[k];
    const Eigen::Vector3f to_light = light.position - p;
    const float d_sq = to_light.squaredNorm();
    const Eigen::Vector3f l = to_light / std::sqrt(d_sq);
    const float lambert = std::max(0.0f, n_in.dot(l));
    float spec = 0.0f;
    if (lambert > 0.0f && m.specular > 0.0) {
      const Eigen::Vector3f h = (l + to_camera).normalized();
      spec = float(m.specular) * power(std::max(0.0f, n_in.dot(h)), m.shininess);
    }
    const float vis = visibility ? visibility[k] : 1.0f;
    const float direct = vis * (float(m.diffuse) * lambert + spec);
    rgb += light.color * ((float(m.ambient) + direct) * light.d0_sq / d_sq);
  }
  return rgb;
}

void shade_span(const Shader& shader, const ShadeSpan& in, float* rgb) {
  const int n = in.count;
  thread_local std::vector<float> buf;
  buf.resize(std::size_t(n) * 9);
  float* vx = buf.data();
  float* vy = vx + n;
  float* vz = vy + n;
  float* acc_r = vz + n;
  float* acc_g = acc_r + n;
  float* acc_b = acc_g + n;
  float* lambert = acc_b + n;
  float* spec = lambert + n;
  float* falloff = spec + n;
  const ShadingModel& m = shader.model;
  const float cx = shader.camera.x(), cy = shader.camera.y(), cz = shader.camera.z();
  for (int i = 0; i < n; ++i) {
    const float x = cx - in.px[i], y = cy - in.py[i], z = cz - in.pz[i];
    const float inv = 1.0f / std::sqrt(x * x + y * y + z * z);
    vx[i] = x * inv;
    vy[i] = y * inv;
    vz[i] = z * inv;
    acc_r[i] = acc_g[i] = acc_b[i] = 0.0f;
  }
  const float ambient = float(m.ambient), diffuse = float(m.diffuse), specular = float(m.specular);
  for (std::size_t k = 0; k < shader.lights.size(); ++k) {
    const ShadingLight& light = shader.lights[k];
    const float lx0 = light.position.x(), ly0 = light.position.y(), lz0 = light.position.z();
    for (int i = 0; i < n; ++i) {
      float lx = lx0 - in.px[i], ly = ly0 - in.py[i], lz = lz0 - in.pz[i];
      const float d_sq = lx * lx + ly * ly + lz * lz;
      const float inv = 1.0f / std::sqrt(d_sq);
      lx *= inv;
      ly *= inv;
      lz *= inv;
      // The coating faces the camera: its normal is -n.
      const float ndotl = -(in.nx[i] * lx + in.ny[i] * ly + in.nz[i] * lz);
      const float hx = lx + vx[i], hy = ly + vy[i], hz = lz + vz[i];
      const float ndoth = -(in.nx[i] * hx + in.ny[i] * hy + in.nz[i] * hz) /
                          std::sqrt(hx * hx + hy * hy + hz * hz);
      lambert[i] = std::max(0.0f, ndotl);
      spec[i] = ndotl > 0.0f ? std::max(0.0f, ndoth) : 0.0f;
      falloff[i] = light.d0_sq / d_sq;
    }
    // spec^shininess by binary powering, each step a vector loop.
    float* base = spec;
    thread_local std::vector<float> power_buf;
    power_buf.assign(std::size_t(n), 1.0f);
    float* result = power_buf.data();
    for (int e = m.shininess; e > 0; e >>= 1) {
      if (e & 1) {
        for (int i = 0; i < n; ++i) result[i] *= base[i];
      }
      for (int i = 0; i < n; ++i) base[i] *= base[i];
    }
    const float* vis = in.visibility ? in.visibility + std::size_t(k) * n : nullptr;
    const float r = light.color.x(), g = light.color.y(), b = light.color.z();
    for (int i = 0; i < n; ++i) {
      const float v = vis ? vis[i] : 1.0f;
      const float w = (ambient + v * (diffuse * lambert[i] + specular * result[i])) * falloff[i];
      acc_r[i] += r * w;
      acc_g[i] += g * w;
      acc_b[i] += b * w;
    }
  }
  for (int i = 0; i < n; ++i) {
    rgb[3 * i] = acc_r[i];
    rgb[3 * i + 1] = acc_g[i];
    rgb[3 * i + 2] = acc_b[i];
  }
}

void light_visibility(const Shader& shader, const GelGeometry& g, const SensorModel& sensor,
                      const float* u, const PixelRect& rect, int i, float* visibility) {
  constexpr int kSteps = 24;
  const Eigen::Vector3f p = g.point(i, u[i]);
  const auto& cam = sensor.camera;
  for (std::size_t k = 0; k < shader.lights.size(); ++k) {
    const Eigen::Vector3f to_light = shader.lights[k].position - p;
    // Only the dented part of the surface can block: march until the path drops below the
    // deepest point of the deformed region (a conservative 2 * max indentation below the gel).
    const float z_stop = g.z_gel_min - 2.0f * float(sensor.gel.max_indentation_m);
    const float s_end =
        to_light.z() < 0.0f ? std::min(1.0f, (z_stop - p.z()) / to_light.z()) : 1.0f;
    float blocked = 0.0f;
    for (int s = 1; s <= kSteps; ++s) {
      const Eigen::Vector3f q = p + to_light * (s_end * float(s) / kSteps);
      const float depth = q.z() + float(cam.distance_m);
      if (depth <= 0.0f) break;
      const int x = int(std::lround(cam.fx * q.x() / depth + cam.cx));
      const int y = int(std::lround(cam.fy * q.y() / depth + cam.cy));
      if (!rect.contains(x, y)) continue;
      const int j = g.index(x, y);
      // The surface z seen through pixel j; the path is outside the gel where it is above it.
      const float z_surface = g.point(j, u[j]).z();
      if (q.z() > z_surface + 1e-6f) {
        blocked = 1.0f;
        break;
      }
    }
    visibility[k] = 1.0f - blocked;
  }
}

NoiseTable::NoiseTable() : samples_(std::size_t(1) << 20) {
  // Box-Muller on a fixed splitmix64 stream: the same table on every platform.
  std::uint64_t state = 0x5eed;
  auto uniform = [&] { return (double((state = splitmix64(state)) >> 11) + 0.5) * 0x1.0p-53; };
  for (std::size_t i = 0; i < samples_.size(); i += 2) {
    const double r = std::sqrt(-2.0 * std::log(uniform())), a = 2.0 * M_PI * uniform();
    samples_[i] = float(r * std::cos(a));
    samples_[i + 1] = float(r * std::sin(a));
  }
}

void NoiseTable::apply(const float* values_255, std::uint8_t* out, std::size_t n, float sigma,
                       std::uint64_t seed, std::size_t position) const {
  // Sequential reads from a seeded offset: frames see shifted copies of one long stream, so a
  // pixel's noise is independent from frame to frame, and the reads stay cache-friendly.
  const std::size_t size = samples_.size();
  std::size_t offset = (std::size_t(splitmix64(seed)) + position) & (size - 1);
  for (std::size_t i = 0; i < n;) {
    const std::size_t run = std::min(n - i, size - offset);
    const float* noise = samples_.data() + offset;
    for (std::size_t k = 0; k < run; ++k) {
      const float v = values_255[i + k] + sigma * noise[k];
      out[i + k] = std::uint8_t(std::clamp(v + 0.5f, 0.0f, 255.0f));
    }
    i += run;
    offset = 0;
  }
}

}  // namespace pg
