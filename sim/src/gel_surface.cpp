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

ElasticKernel make_elastic_kernel(const ElasticModel& model, float px_per_m, int longest_line) {
  ElasticKernel k;
  if (!model.enabled) return k;
  k.enabled = true;
  k.alpha = float(1.0 / (2.0 * model.bend_radius_m * double(px_per_m) * double(px_per_m)));
  const double sigma_px = model.smoothing_m * px_per_m;
  k.blur_radius = sigma_px < 0.3 ? 0 : gaussian_box_radius(sigma_px);
  k.inv_2alpha_k.resize(std::size_t(longest_line) + 1, 0.0f);
  for (int d = 1; d <= longest_line; ++d) k.inv_2alpha_k[d] = 1.0f / (2.0f * k.alpha * float(d));
  return k;
}

int ElasticKernel::reach(float depth_m) const {
  if (!enabled) return 0;
  // A parabola hanging from depth_m stays positive for sqrt(depth_m / alpha) pixels; one more
  // pixel keeps a rounding error at that distance inside the rectangle.
  return int(std::ceil(std::sqrt(std::max(depth_m, 0.0f) / alpha))) + 1;
}

namespace {

struct LineScratch {
  std::vector<int> v;
  std::vector<float> z, line, out;
};

// The upper envelope of the parabolas g[q] - alpha (x - q)^2 hanging from q in [q0, q1)
// (Felzenszwalb and Huttenlocher's lower-envelope scan, O(n)), evaluated at x in [x0, x1) into
// out[x - x0]; x may lie outside [q0, q1). inv[k] = 1 / (2 alpha k).
void parabola_envelope(const float* g, int q0, int q1, int x0, int x1, float alpha,
                       const float* inv, LineScratch& s, float* out) {
  s.v.resize(std::size_t(q1 - q0));
  s.z.resize(std::size_t(q1 - q0) + 1);
  int* v = s.v.data();
  float* z = s.z.data();
  // x where the parabolas hanging from p < q meet.
  auto meet = [&](int p, int q) { return 0.5f * float(p + q) + (g[p] - g[q]) * inv[q - p]; };
  int k = 0;
  v[0] = q0;
  z[0] = -INFINITY;
  z[1] = INFINITY;
  for (int q = q0 + 1; q < q1; ++q) {
    float m = meet(v[k], q);
    while (m <= z[k]) {
      --k;
      m = meet(v[k], q);
    }
    ++k;
    v[k] = q;
    z[k] = m;
    z[k + 1] = INFINITY;
  }
  k = 0;
  for (int x = x0; x < x1; ++x) {
    while (z[k + 1] < float(x)) ++k;
    const float d = float(x - v[k]);
    out[x - x0] = g[v[k]] - alpha * d * d;
  }
}

// [first, last + 1) of the positive values of line[lo, hi); empty (first >= second) if none.
std::pair<int, int> positive_span(const float* line, int lo, int hi) {
  int a = lo;
  while (a < hi && !(line[a] > 0.0f)) ++a;
  int b = hi;
  while (b > a && !(line[b - 1] > 0.0f)) --b;
  return {a, b};
}

// The column passes, a block of columns at a time: rows [in_y0, in_y1) of the block are copied
// into contiguous columns (reading row segments, rather than one value per cache line),
// column(x, in, out) runs on each (in and out indexed by image row), and rows
// [out_y0, out_y1) of its output are copied back into dst.
template <typename Column>
void by_column_blocks(const float* src, float* dst, int width, int height, int x0, int x1,
                      int in_y0, int in_y1, int out_y0, int out_y1, Column&& column) {
  constexpr int kBlock = 16;
  thread_local std::vector<float> in_cols, out_cols;
  in_cols.resize(std::size_t(kBlock) * height);
  out_cols.resize(in_cols.size());
  for (int xb = x0; xb < x1; xb += kBlock) {
    const int n = std::min(kBlock, x1 - xb);
    for (int y = in_y0; y < in_y1; ++y) {
      const float* row = src + std::size_t(y) * width + xb;
      for (int j = 0; j < n; ++j) in_cols[std::size_t(j) * height + y] = row[j];
    }
    for (int j = 0; j < n; ++j) {
      column(xb + j, &in_cols[std::size_t(j) * height], &out_cols[std::size_t(j) * height]);
    }
    for (int y = out_y0; y < out_y1; ++y) {
      float* row = dst + std::size_t(y) * width + xb;
      for (int j = 0; j < n; ++j) row[j] = out_cols[std::size_t(j) * height + y];
    }
  }
}

// Dilation of `rigid` (zero outside `contact`) into `dil`, written on all of `outer` (which holds
// the contact dilated by the kernel's reach), via `rows`. Returns the bounding box of the
// positive values. Each line's envelope holds only the parabolas of its positive span: the
// zeros around it add nothing above zero, so the result is clamped to zero instead.
PixelRect dilate(const ElasticKernel& k, int width, int height, const PixelRect& contact,
                 const PixelRect& outer, const float* rigid, float* rows, float* dil,
                 LineScratch& s) {
  const float* inv = k.inv_2alpha_k.data();
  for (int y = contact.y0; y < contact.y1; ++y) {
    const float* in = rigid + std::size_t(y) * width;
    float* out = rows + std::size_t(y) * width + outer.x0;
    const auto [a, b] = positive_span(in, contact.x0, contact.x1);
    if (a >= b) {
      std::fill_n(out, outer.width(), 0.0f);
      continue;
    }
    parabola_envelope(in, a, b, outer.x0, outer.x1, k.alpha, inv, s, out);
    for (int x = 0; x < outer.width(); ++x) out[x] = std::max(out[x], 0.0f);
  }
  PixelRect positive;
  by_column_blocks(rows, dil, width, height, outer.x0, outer.x1, contact.y0, contact.y1, outer.y0,
                   outer.y1, [&](int x, float* in, float* out) {
                     const auto [a, b] = positive_span(in, contact.y0, contact.y1);
                     if (a >= b) {
                       std::fill(out + outer.y0, out + outer.y1, 0.0f);
                       return;
                     }
                     parabola_envelope(in, a, b, outer.y0, outer.y1, k.alpha, inv, s,
                                       out + outer.y0);
                     int first = outer.y1, last = outer.y0 - 1;
                     for (int y = outer.y0; y < outer.y1; ++y) {
                       out[y] = std::max(out[y], 0.0f);
                       if (out[y] > 0.0f) {
                         first = std::min(first, y);
                         last = y;
                       }
                     }
                     if (first <= last) positive = positive.united({x, first, x + 1, last + 1});
                   });
  return positive;
}

// Erosion of `dil` (zero outside `rect`, the box of its positive values) into `out` on `rect`,
// via `rows`. Outside a line's positive span the erosion is zero; inside it, among the zeros
// only the nearest one on each side can be the minimum, so the envelope needs only those.
// The erosion is the dilation of -dil, flipped back.
void erode(const ElasticKernel& k, int width, int height, const PixelRect& rect, const float* dil,
           float* rows, float* out, LineScratch& s) {
  const float* inv = k.inv_2alpha_k.data();
  s.line.resize(std::size_t(std::max(width, height)));
  s.out.resize(s.line.size());
  float* line = s.line.data();
  for (int y = rect.y0; y < rect.y1; ++y) {
    const float* in = dil + std::size_t(y) * width;
    float* dst = rows + std::size_t(y) * width;
    const auto [a, b] = positive_span(in, rect.x0, rect.x1);
    const int q0 = std::max(a - 1, 0), q1 = std::min(b + 1, width);
    for (int q = q0; q < q1; ++q) line[q] = -in[q];
    for (int x = rect.x0; x < rect.x1; ++x) dst[x] = 0.0f;
    if (a >= b) continue;
    parabola_envelope(line, q0, q1, a, b, k.alpha, inv, s, s.out.data());
    for (int x = a; x < b; ++x) dst[x] = -s.out[x - a];
  }
  by_column_blocks(rows, out, width, height, rect.x0, rect.x1, rect.y0, rect.y1, rect.y0, rect.y1,
                   [&](int, float* in, float* col_out) {
                     std::fill(col_out + rect.y0, col_out + rect.y1, 0.0f);
                     int a = rect.y0, b = rect.y1;
                     while (a < b && !(in[a] > 0.0f)) ++a;
                     while (b > a && !(in[b - 1] > 0.0f)) --b;
                     if (a >= b) return;
                     // Negate, with the zeros just outside the span (if in the image).
                     const int q0 = std::max(a - 1, 0), q1 = std::min(b + 1, height);
                     for (int y = q0; y < q1; ++y) {
                       in[y] = (y < rect.y0 || y >= rect.y1) ? 0.0f : -in[y];
                     }
                     parabola_envelope(in, q0, q1, a, b, k.alpha, inv, s, col_out + a);
                     for (int y = a; y < b; ++y) col_out[y] = -col_out[y];
                   });
}

// One box pass of radius r over n values of a line that has r zeros of padding on each side
// (in[-r .. n + r)): out[x] = mean of in[x - r .. x + r]. A direct sum, so that it vectorises.
void box_line(const float* in, float* out, int n, int r) {
  const float inv = 1.0f / float(2 * r + 1);
  for (int x = 0; x < n; ++x) out[x] = in[x - r];
  for (int j = 1 - r; j <= r; ++j)
    for (int x = 0; x < n; ++x) out[x] += in[x + j];
  for (int x = 0; x < n; ++x) out[x] *= inv;
}

}  // namespace

int gaussian_box_radius(double sigma_px) {
  // Three box passes of width w have variance 3 (w^2 - 1) / 12 = sigma^2.
  const double w = std::sqrt(4.0 * sigma_px * sigma_px + 1.0);
  return std::max(1, int(std::lround((w - 1.0) / 2.0)));
}

void gaussian_blur(const float* src, float* dst, float* scratch, int width, const PixelRect& rect,
                   int r) {
  if (rect.empty()) return;
  const int n = rect.width();
  // Rows: three passes along a zero-padded copy of each row, src -> scratch (may be src).
  thread_local std::vector<float> line_a, line_b;
  line_a.assign(std::size_t(n + 2 * r), 0.0f);
  line_b.assign(line_a.size(), 0.0f);
  float* a = line_a.data() + r;
  float* b = line_b.data() + r;
  for (int y = rect.y0; y < rect.y1; ++y) {
    const std::size_t row = std::size_t(y) * width + rect.x0;
    std::copy_n(src + row, n, a);
    box_line(a, b, n, r);
    box_line(b, a, n, r);
    box_line(a, scratch + row, n, r);
  }
  // Columns: three passes, each a row of outputs at a time so that the inner loops run along x:
  // scratch -> dst -> scratch -> dst. Rows outside rect count as zero.
  const float inv = 1.0f / float(2 * r + 1);
  auto column_pass = [&](const float* in, float* out) {
    for (int y = rect.y0; y < rect.y1; ++y) {
      float* o = out + std::size_t(y) * width + rect.x0;
      std::fill_n(o, n, 0.0f);
      for (int yy = std::max(y - r, rect.y0); yy <= std::min(y + r, rect.y1 - 1); ++yy) {
        const float* i = in + std::size_t(yy) * width + rect.x0;
        for (int x = 0; x < n; ++x) o[x] += i[x];
      }
      for (int x = 0; x < n; ++x) o[x] *= inv;
    }
  };
  column_pass(scratch, dst);
  column_pass(dst, scratch);
  column_pass(scratch, dst);
}

PixelRect elastic_displacement(const ElasticKernel& kernel, int width, int height,
                               const PixelRect& contact, float deepest, const float* rigid,
                               float* scratch_a, float* scratch_b, float* u) {
  if (contact.empty()) return {};
  if (!kernel.enabled) {
    for (int y = contact.y0; y < contact.y1; ++y) {
      const std::size_t row = std::size_t(y) * width;
      std::copy(rigid + row + contact.x0, rigid + row + contact.x1, u + row + contact.x0);
    }
    return contact;
  }
  thread_local LineScratch s;
  // Closing = erosion of the dilation: rigid -> (a) -> b (dilated) -> (a) -> u (closed).
  const PixelRect outer = contact.dilated(kernel.reach(deepest)).clipped(width, height);
  const PixelRect dilated =
      dilate(kernel, width, height, contact, outer, rigid, scratch_a, scratch_b, s);
  erode(kernel, width, height, dilated, scratch_b, scratch_a, u, s);
  PixelRect moved = dilated;
  const float* surface = u;
  if (kernel.blur_radius > 0) {
    // u is zero around `dilated`, as the blur requires.
    moved = dilated.dilated(3 * kernel.blur_radius).clipped(width, height);
    gaussian_blur(u, scratch_b, scratch_a, width, moved, kernel.blur_radius);
    surface = scratch_b;
  }
  for (int y = moved.y0; y < moved.y1; ++y) {
    for (int x = moved.x0; x < moved.x1; ++x) {
      const std::size_t i = std::size_t(y) * width + x;
      u[i] = std::max(rigid[i], surface[i]);  // the closing is >= r; smoothing may dip below
    }
  }
  return moved;
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
