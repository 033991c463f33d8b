#include "gel_surface.h"

#include <cmath>

namespace pg {

GelGeometry make_gel_geometry(const SensorModel& sensor) {
  const CameraModel& cam = sensor.camera;
  GelGeometry g;
  g.width = cam.width;
  g.height = cam.height;
  g.origin_sensor = Eigen::Vector3f(0, 0, float(-cam.distance_m));
  g.dir_sensor.resize(std::size_t(cam.width) * cam.height);
  g.t_gel.resize(g.dir_sensor.size());
  g.px_per_m = float(cam.fy / cam.distance_m);
  g.z_gel_min = 0.0f;
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const Eigen::Vector3d d = cam.ray(x, y);
      // Where the ray meets the convex gel: z = surface_z(x(z), y(z)); a fixed-point iteration
      // converges fast because the gel's slope is small.
      double z = 0.0;
      for (int it = 0; it < 20; ++it) {
        const double t = z + cam.distance_m;
        const double z_next = sensor.gel.surface_z(d.x() * t, d.y() * t);
        const bool done = std::abs(z_next - z) < 1e-12;
        z = z_next;
        if (done) break;
      }
      const int i = g.index(x, y);
      g.dir_sensor[i] = d.cast<float>();
      g.t_gel[i] = float(z + cam.distance_m);
      g.z_gel_min = std::min(g.z_gel_min, float(z));
    }
  }
  return g;
}

ElasticKernel make_elastic_kernel(const ElasticModel& model, float px_per_m) {
  ElasticKernel k;
  if (!model.enabled) return k;
  k.enabled = true;
  k.alpha = float(1.0 / (2.0 * model.bend_radius_m * double(px_per_m) * double(px_per_m)));
  const double sigma_px = model.smoothing_m * px_per_m;
  k.blur_radius = sigma_px < 0.3 ? 0 : gaussian_box_radius(sigma_px);
  return k;
}

int ElasticKernel::support(float depth_m) const {
  if (!enabled) return 0;
  // The closing never reaches beyond the dilation's reach.
  return int(std::ceil(std::sqrt(std::max(depth_m, 0.0f) / alpha))) + 3 * blur_radius + 1;
}

namespace {

// Box blur of radius r along rows (dx = 1) or columns (dx = width) over rect, treating values
// outside rect as zero. src and dst may not alias.
void box_pass(const float* src, float* dst, int width, const PixelRect& rect, int r, bool rows) {
  const float inv = 1.0f / float(2 * r + 1);
  const int outer0 = rows ? rect.y0 : rect.x0, outer1 = rows ? rect.y1 : rect.x1;
  const int lo = rows ? rect.x0 : rect.y0, hi = rows ? rect.x1 : rect.y1;
  const long step = rows ? 1 : width;
  for (int o = outer0; o < outer1; ++o) {
    const long base = rows ? long(o) * width : o;
    auto at = [&](int k) { return (k >= lo && k < hi) ? src[base + k * step] : 0.0f; };
    float sum = 0.0f;
    for (int k = lo - r; k <= lo + r; ++k) sum += at(k);
    for (int k = lo; k < hi; ++k) {
      dst[base + k * step] = sum * inv;
      sum += at(k + r + 1) - at(k - r);
    }
  }
}

// One line of a morphological operation with the parabola alpha d^2 (Felzenszwalb and
// Huttenlocher's lower-envelope scan, O(n)): dilation out(x) = max_q f(q) - alpha (x - q)^2 for
// sign = +1, erosion out(x) = min_q f(q) + alpha (x - q)^2 for sign = -1.
void parabolic_line(const float* f, float* out, int n, long step, float alpha, float sign,
                    std::vector<int>& v, std::vector<float>& z) {
  v.resize(n);
  z.resize(n + 1);
  auto g = [&](int q) { return sign * f[q * step]; };  // dilate g, then flip back
  // x where the parabolas hanging from p < q meet.
  auto meet = [&](int p, int q) {
    return 0.5f * (float(p + q) + (g(p) - g(q)) / (alpha * float(q - p)));
  };
  int k = 0;
  v[0] = 0;
  z[0] = -INFINITY;
  z[1] = INFINITY;
  for (int q = 1; q < n; ++q) {
    float s = meet(v[k], q);
    while (s <= z[k]) {
      --k;
      s = meet(v[k], q);
    }
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = INFINITY;
  }
  k = 0;
  for (int x = 0; x < n; ++x) {
    while (z[k + 1] < float(x)) ++k;
    const float d = float(x - v[k]);
    out[x * step] = sign * (g(v[k]) - alpha * d * d);
  }
}

// Separable 2D version over rect (|d|^2 = dx^2 + dy^2): src -> dst via tmp.
void parabolic_2d(const float* src, float* tmp, float* dst, int width, const PixelRect& rect,
                  float alpha, float sign) {
  thread_local std::vector<int> v;
  thread_local std::vector<float> z;
  for (int y = rect.y0; y < rect.y1; ++y) {
    const long base = long(y) * width + rect.x0;
    parabolic_line(src + base, tmp + base, rect.width(), 1, alpha, sign, v, z);
  }
  for (int x = rect.x0; x < rect.x1; ++x) {
    const long base = long(rect.y0) * width + x;
    parabolic_line(tmp + base, dst + base, rect.height(), width, alpha, sign, v, z);
  }
}

}  // namespace

int gaussian_box_radius(double sigma_px) {
  // Three box passes of width w have variance 3 (w^2 - 1) / 12 = sigma^2.
  const double w = std::sqrt(4.0 * sigma_px * sigma_px + 1.0);
  return std::max(1, int(std::lround((w - 1.0) / 2.0)));
}

void gaussian_blur(const float* src, float* dst, float* scratch, int width, const PixelRect& rect,
                   int r) {
  box_pass(src, dst, width, rect, r, true);
  box_pass(dst, scratch, width, rect, r, false);
  box_pass(scratch, dst, width, rect, r, true);
  box_pass(dst, scratch, width, rect, r, false);
  box_pass(scratch, dst, width, rect, r, true);
  box_pass(dst, scratch, width, rect, r, false);
  for (int y = rect.y0; y < rect.y1; ++y) {
    for (int x = rect.x0; x < rect.x1; ++x) dst[y * width + x] = scratch[y * width + x];
  }
}

void elastic_displacement(const ElasticKernel& kernel, int width, const PixelRect& rect,
                          const float* rigid, float* scratch, float* u) {
  if (!kernel.enabled) {
    for (int y = rect.y0; y < rect.y1; ++y) {
      for (int x = rect.x0; x < rect.x1; ++x) u[y * width + x] = rigid[y * width + x];
    }
    return;
  }
  // Closing = erosion of the dilation: rigid -> u (dilated) -> u (closed), via scratch; then
  // the smoothing u -> scratch.
  parabolic_2d(rigid, scratch, u, width, rect, kernel.alpha, 1.0f);
  parabolic_2d(u, scratch, u, width, rect, kernel.alpha, -1.0f);
  const float* surface = u;
  if (kernel.blur_radius > 0) {
    gaussian_blur(u, scratch, u, width, rect, kernel.blur_radius);
    surface = scratch;
  }
  for (int y = rect.y0; y < rect.y1; ++y) {
    for (int x = rect.x0; x < rect.x1; ++x) {
      const int i = y * width + x;
      u[i] = std::max(rigid[i], surface[i]);  // the closing is >= r; smoothing may dip below
    }
  }
}

void surface_normals(const GelGeometry& g, const float* u, const PixelRect& rect, float* normals) {
  for (int y = rect.y0; y < rect.y1; ++y) {
    const int ym = std::max(y - 1, 0), yp = std::min(y + 1, g.height - 1);
    for (int x = rect.x0; x < rect.x1; ++x) {
      const int xm = std::max(x - 1, 0), xp = std::min(x + 1, g.width - 1);
      const int im = g.index(xm, y), ip = g.index(xp, y), jm = g.index(x, ym), jp = g.index(x, yp);
      const Eigen::Vector3f dx = g.point(ip, u[ip]) - g.point(im, u[im]);
      const Eigen::Vector3f dy = g.point(jp, u[jp]) - g.point(jm, u[jm]);
      const Eigen::Vector3f n = dx.cross(dy).normalized();
      float* out = normals + 3 * std::size_t(g.index(x, y));
      out[0] = n.x();
      out[1] = n.y();
      out[2] = n.z();
    }
  }
}

}  // namespace pg
