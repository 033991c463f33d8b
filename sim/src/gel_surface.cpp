#include "gel_surface.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace pg {

GelGeometry make_gel_geometry(const SensorModel& sensor) {
  GelGeometry g;
  static_cast<GelRays&>(g) = make_gel_rays(sensor.camera, sensor.gel);
  g.dir_x.resize(g.dir_sensor.size());
  g.dir_y.resize(g.dir_sensor.size());
  g.z_gel_min = 0.0f;
  for (std::size_t i = 0; i < g.dir_sensor.size(); ++i) {
    g.dir_x[i] = g.dir_sensor[i].x();
    g.dir_y[i] = g.dir_sensor[i].y();
    g.z_gel_min = std::min(g.z_gel_min, g.point(int(i), 0.0f).z());
  }
  // The radial bound: each pixel's gel point into the bin of its squared distance from the
  // axis, then the maximum over each bin and all bins beyond it.
  constexpr int kBins = 256;
  std::vector<float> rho_sq(g.t_gel.size());
  float rho_sq_max = 0;
  for (std::size_t i = 0; i < rho_sq.size(); ++i) {
    const Eigen::Vector3f p = g.point(int(i), 0.0f);
    rho_sq[i] = p.x() * p.x() + p.y() * p.y();
    rho_sq_max = std::max(rho_sq_max, rho_sq[i]);
  }
  g.rho_sq_step = std::max(rho_sq_max, 1e-12f) / float(kBins - 1);
  g.highest_z.assign(kBins, -std::numeric_limits<float>::infinity());
  for (std::size_t i = 0; i < rho_sq.size(); ++i) {
    const int b = std::min(int(rho_sq[i] / g.rho_sq_step), kBins - 1);
    g.highest_z[b] = std::max(g.highest_z[b], g.t_gel[i] + g.origin_sensor.z());
  }
  for (int b = kBins - 2; b >= 0; --b)
    g.highest_z[b] = std::max(g.highest_z[b], g.highest_z[b + 1]);
  return g;
}

namespace {

// The normal at pixel i from its neighbours im, ip (along x) and jm, jp (along y): the cross
// product of the central differences of the displaced surface points
// P = origin + dir (t_gel - u).
inline void normal_from_neighbours(const float* __restrict dx, const float* __restrict dy,
                                   const float* __restrict t, const float* __restrict u, float oz,
                                   int im, int ip, int jm, int jp, float* __restrict out) {
  const float s_im = t[im] - u[im], s_ip = t[ip] - u[ip], s_jm = t[jm] - u[jm],
              s_jp = t[jp] - u[jp];
  const float ax = dx[ip] * s_ip - dx[im] * s_im, ay = dy[ip] * s_ip - dy[im] * s_im;
  const float az = (oz + s_ip) - (oz + s_im);
  const float bx = dx[jp] * s_jp - dx[jm] * s_jm, by = dy[jp] * s_jp - dy[jm] * s_jm;
  const float bz = (oz + s_jp) - (oz + s_jm);
  const float nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
  const float norm = std::sqrt(nx * nx + ny * ny + nz * nz);
  out[0] = nx / norm;
  out[1] = ny / norm;
  out[2] = nz / norm;
}

// The same for n pixels of a row whose x-neighbours are all in the image; the arrays start at
// the row's first pixel, `up` and `down` are the offsets to the rows above and below. Not
// inlined: GCC 12 drops the restrict qualifiers when it inlines, and then cannot vectorise.
__attribute__((noinline)) void normals_row(int n, const float* __restrict dx,
                                           const float* __restrict dy, const float* __restrict t,
                                           const float* __restrict u, float oz, int up, int down,
                                           float* __restrict out) {
  for (int i = 0; i < n; ++i) {
    normal_from_neighbours(dx, dy, t, u, oz, i - 1, i + 1, i + up, i + down, out + 3 * i);
  }
}

}  // namespace

void surface_normals(const GelGeometry& g, const float* u, const PixelRect& rect, float* normals) {
  const int w = g.width;
  const float oz = g.origin_sensor.z();
  const float *dx = g.dir_x.data(), *dy = g.dir_y.data(), *t = g.t_gel.data();
  for (int y = rect.y0; y < rect.y1; ++y) {
    const int up = (std::max(y - 1, 0) - y) * w, down = (std::min(y + 1, g.height - 1) - y) * w;
    // The image's first and last columns clamp their neighbour; the rest is one vector loop.
    auto clamped = [&](int x) {
      const int i = g.index(x, y);
      normal_from_neighbours(dx, dy, t, u, oz, g.index(std::max(x - 1, 0), y),
                             g.index(std::min(x + 1, w - 1), y), i + up, i + down,
                             normals + 3 * std::size_t(i));
    };
    const int x0 = std::max(rect.x0, 1), x1 = std::min(rect.x1, w - 1);
    if (rect.x0 < x0) clamped(rect.x0);
    if (x1 > x0) {
      const int i = g.index(x0, y);
      normals_row(x1 - x0, dx + i, dy + i, t + i, u + i, oz, up, down,
                  normals + 3 * std::size_t(i));
    }
    if (x1 >= x0 && rect.x1 > x1) clamped(rect.x1 - 1);
  }
}

}  // namespace pg
