#include "change_filter.h"

#include <algorithm>
#include <cmath>

#include "pg/core/gel_elastic.h"

namespace pg {

namespace {

// The kernel is cut where what lies beyond holds less than this share of its absolute sum.
constexpr double kTailShare = 0.01;

// The kernel reaches at most this far (a blur of more than 3 px is cut there; its Wiener kernel
// costs (2 r + 1)^2 multiplications per pixel and channel).
constexpr int kLargestReach = 24;

int mirrored(int i, int n) {
  if (n == 1) return 0;
  while (i < 0 || i >= n) i = i < 0 ? -i : 2 * (n - 1) - i;
  return i;
}

}  // namespace

ChangeFilter::ChangeFilter(double blur_px, double noise_to_signal) {
  // The blur as the renderer applies it: its truncated, normalised Gaussian.
  const GaussianKernel blur = gaussian_kernel(blur_px);
  if (blur.weights.empty() || !(noise_to_signal > 0)) return;
  const int reach = std::clamp(int(std::ceil(8.0 * blur_px)), 2, kLargestReach);
  int n = 256;
  while (n < 4 * (2 * reach + 1)) n *= 2;
  // The blur's transfer along one axis at n frequencies f in (-1/2, 1/2), and the filter's.
  std::vector<double> f(n), g(n);
  for (int i = 0; i < n; ++i) {
    f[i] = (i + 0.5) / n - 0.5;
    double v = blur.weights[0];
    for (int j = 1; j <= blur.radius(); ++j)
      v += 2.0 * blur.weights[j] * std::cos(2.0 * M_PI * j * f[i]);
    g[i] = v;
  }
  const double k = noise_to_signal;
  // The filter is even in each axis: its kernel is the cosine sum over both frequencies.
  const int side = 2 * reach + 1;
  std::vector<double> cosines(std::size_t(side) * n);
  for (int x = -reach; x <= reach; ++x)
    for (int i = 0; i < n; ++i)
      cosines[std::size_t(x + reach) * n + i] = std::cos(2 * M_PI * x * f[i]);
  // Along the first axis: rows[x][j] = sum_i cos(2 pi x f_i) H(f_i, f_j) / n.
  std::vector<double> rows(std::size_t(side) * n, 0.0);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double G = g[i] * g[j];
      const double h = G * (1.0 + k) / (G * G + k) / n;
      for (int x = 0; x < side; ++x)
        rows[std::size_t(x) * n + j] += cosines[std::size_t(x) * n + i] * h;
    }
  }
  std::vector<double> full(std::size_t(side) * side, 0.0);
  for (int x = 0; x < side; ++x)
    for (int y = 0; y < side; ++y) {
      double v = 0.0;
      for (int j = 0; j < n; ++j)
        v += rows[std::size_t(x) * n + j] * cosines[std::size_t(y) * n + j];
      full[std::size_t(y) * side + x] = v / n;
    }
  // The smallest radius whose kernel holds all but kTailShare of the absolute sum.
  double total = 0.0;
  for (double v : full) total += std::abs(v);
  radius_ = reach;
  for (int r = 1; r < reach; ++r) {
    double inside = 0.0;
    for (int y = reach - r; y <= reach + r; ++y)
      for (int x = reach - r; x <= reach + r; ++x)
        inside += std::abs(full[std::size_t(y) * side + x]);
    if (total - inside < kTailShare * total) {
      radius_ = r;
      break;
    }
  }
  // Cut and normalised, so that a uniform change passes unchanged.
  const int cut = 2 * radius_ + 1;
  kernel_.resize(std::size_t(cut) * cut);
  double sum = 0.0;
  for (int y = 0; y < cut; ++y)
    for (int x = 0; x < cut; ++x)
      sum += full[std::size_t(y + reach - radius_) * side + x + reach - radius_];
  for (int y = 0; y < cut; ++y)
    for (int x = 0; x < cut; ++x)
      kernel_[std::size_t(y) * cut + x] =
          float(full[std::size_t(y + reach - radius_) * side + x + reach - radius_] / sum);
}

void ChangeFilter::change_at(const ImageU8& color, const ImageU8& reference,
                             const std::vector<int>& pixels, std::vector<float>& out) const {
  const int w = color.width, h = color.height;
  out.assign(3 * pixels.size(), 0.0f);
  if (!active()) {
    for (std::size_t j = 0; j < pixels.size(); ++j)
      for (int c = 0; c < 3; ++c) {
        const std::size_t at = 3 * std::size_t(pixels[j]) + c;
        out[3 * j + c] = float(color.data[at]) - float(reference.data[at]);
      }
    return;
  }
  std::vector<float> change(color.data.size());
  for (std::size_t i = 0; i < change.size(); ++i)
    change[i] = float(color.data[i]) - float(reference.data[i]);
  const int r = radius_, side = 2 * r + 1;
  for (std::size_t j = 0; j < pixels.size(); ++j) {
    const int x = pixels[j] % w, y = pixels[j] / w;
    float sum[3] = {0.0f, 0.0f, 0.0f};
    const bool inside = x >= r && y >= r && x + r < w && y + r < h;
    for (int dy = -r; dy <= r; ++dy) {
      const int yy = inside ? y + dy : mirrored(y + dy, h);
      const float* k = &kernel_[std::size_t(dy + r) * side];
      for (int dx = -r; dx <= r; ++dx) {
        const int xx = inside ? x + dx : mirrored(x + dx, w);
        const float* d = &change[3 * (std::size_t(yy) * w + xx)];
        const float weight = k[dx + r];
        sum[0] += weight * d[0], sum[1] += weight * d[1], sum[2] += weight * d[2];
      }
    }
    for (int c = 0; c < 3; ++c) out[3 * j + c] = sum[c];
  }
}

}  // namespace pg
