#include "pg/core/gel_elastic.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace pg {

ElasticKernel make_elastic_kernel(const ElasticModel& model, float px_per_m, int longest_line) {
  ElasticKernel k;
  if (!model.enabled) return k;
  k.enabled = true;
  k.alpha = float(1.0 / (2.0 * model.bend_radius_m * double(px_per_m) * double(px_per_m)));
  const double sigma_px = model.smoothing_m * px_per_m;
  k.blur = gaussian_kernel(sigma_px);
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

}  // namespace

GaussianKernel gaussian_kernel(double sigma_px) {
  GaussianKernel k;
  if (!(sigma_px > 0.0) || std::exp(-0.5 / (sigma_px * sigma_px)) < 1e-6) return k;
  const int radius = int(std::ceil(3.0 * sigma_px));
  std::vector<double> w(std::size_t(radius) + 1);
  double sum = 0.0;
  for (int j = 0; j <= radius; ++j) {
    w[j] = std::exp(-0.5 * double(j) * double(j) / (sigma_px * sigma_px));
    sum += j == 0 ? w[j] : 2.0 * w[j];
  }
  for (double v : w) k.weights.push_back(float(v / sum));
  return k;
}

void gaussian_blur(const float* src, float* dst, float* scratch, int width, const PixelRect& rect,
                   const GaussianKernel& kernel) {
  if (rect.empty()) return;
  const int n = rect.width(), r = kernel.radius();
  const std::vector<float>& w = kernel.weights;
  // Rows: along a zero-padded copy of each row, src -> scratch (which may be src).
  thread_local std::vector<float> line;
  line.assign(std::size_t(n + 2 * r), 0.0f);
  const float* a = line.data() + r;
  for (int y = rect.y0; y < rect.y1; ++y) {
    const std::size_t row = std::size_t(y) * width + rect.x0;
    std::copy_n(src + row, n, line.data() + r);
    float* o = scratch + row;
    for (int x = 0; x < n; ++x) o[x] = w[0] * a[x];
    for (int j = 1; j <= r; ++j)
      for (int x = 0; x < n; ++x) o[x] += w[j] * (a[x - j] + a[x + j]);
  }
  // Columns: a row of outputs at a time, so that the inner loop runs along x; scratch -> dst.
  // Rows outside rect count as zero.
  for (int y = rect.y0; y < rect.y1; ++y) {
    float* o = dst + std::size_t(y) * width + rect.x0;
    std::fill_n(o, n, 0.0f);
    for (int yy = std::max(y - r, rect.y0); yy <= std::min(y + r, rect.y1 - 1); ++yy) {
      const float* i = scratch + std::size_t(yy) * width + rect.x0;
      const float wy = w[std::abs(yy - y)];
      for (int x = 0; x < n; ++x) o[x] += wy * i[x];
    }
  }
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
  if (!kernel.blur.weights.empty()) {
    // u is zero around `dilated`, as the blur requires.
    moved = dilated.dilated(kernel.blur.radius()).clipped(width, height);
    gaussian_blur(u, scratch_b, scratch_a, width, moved, kernel.blur);
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

ImageF elastic_indentation(const ElasticModel& model, double px_per_m, const ImageF& rigid) {
  const int w = rigid.width, h = rigid.height;
  PixelRect contact;
  float deepest = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float r = rigid.data[std::size_t(y) * w + x];
      if (r <= 0) continue;
      contact.include(x, y);
      deepest = std::max(deepest, r);
    }
  }
  ImageF u(w, h, 1);
  std::vector<float> a(std::size_t(w) * h), b(std::size_t(w) * h);
  elastic_displacement(make_elastic_kernel(model, float(px_per_m), std::max(w, h) + 2), w, h,
                       contact, deepest, rigid.data.data(), a.data(), b.data(), u.data.data());
  return u;
}

}  // namespace pg
