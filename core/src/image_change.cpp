#include "pg/core/image_change.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace pg {

int ChangedRegions::largest() const {
  if (sizes.empty()) return -1;
  return int(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
}

int ChangedRegions::pixels_in_regions_of(int min_size) const {
  int pixels = 0;
  for (const int size : sizes) pixels += size >= min_size ? size : 0;
  return pixels;
}

ChangedRegions changed_regions(const ImageU8& color, const ImageU8& reference) {
  const int w = color.width, h = color.height;
  ChangedRegions r;
  r.region.assign(std::size_t(w) * h, -1);
  std::vector<int> changed_at;
  for_each_changed_pixel(color, reference, [&](int x, int y) {
    changed_at.push_back(y * w + x);
    return true;
  });
  r.changed = int(changed_at.size());
  // Marked -2 first: changed, in no region yet.
  for (const int i : changed_at) r.region[std::size_t(i)] = -2;
  std::vector<int> stack;
  for (const int start : changed_at) {
    if (r.region[std::size_t(start)] != -2) continue;
    const int index = int(r.sizes.size());
    int size = 1;
    r.region[std::size_t(start)] = index;
    stack.assign(1, start);
    flood_fill(
        w, h, stack, [&](int j) { return r.region[std::size_t(j)] == -2; },
        [&](int j) {
          r.region[std::size_t(j)] = index;
          ++size;
        });
    r.sizes.push_back(size);
  }
  return r;
}

ImageU8 median_image(const std::vector<ImageU8>& images) {
  if (images.empty()) throw std::invalid_argument("median_image: no images");
  for (const ImageU8& image : images) {
    if (image.width != images[0].width || image.height != images[0].height ||
        image.channels != images[0].channels) {
      throw std::invalid_argument("median_image: images of different sizes");
    }
  }
  ImageU8 median = images[0];
  std::vector<std::uint8_t> values(images.size());
  const std::size_t mid = values.size() / 2;
  for (std::size_t i = 0; i < median.data.size(); ++i) {
    for (std::size_t k = 0; k < images.size(); ++k) values[k] = images[k].data[i];
    std::nth_element(values.begin(), values.begin() + mid, values.end());
    int m = values[mid];
    if (values.size() % 2 == 0) {  // the two middle values' mean, rounded up
      m = (m + *std::max_element(values.begin(), values.begin() + mid) + 1) / 2;
    }
    median.data[i] = std::uint8_t(m);
  }
  return median;
}

double noise_levels(const ImageU8& image) {
  const int w = image.width, h = image.height, channels = image.channels;
  if (w < 3 || h < 3) return 0.0;
  // Four times the residual, as integers: |4 p - (left + right + up + down)|.
  std::vector<int> residual;
  residual.reserve(std::size_t(w - 2) * (h - 2) * channels);
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      for (int c = 0; c < channels; ++c) {
        const int around = image.at(x - 1, y, c) + image.at(x + 1, y, c) + image.at(x, y - 1, c) +
                           image.at(x, y + 1, c);
        residual.push_back(std::abs(4 * image.at(x, y, c) - around));
      }
    }
  }
  const auto middle = residual.begin() + std::ptrdiff_t(residual.size() / 2);
  std::nth_element(residual.begin(), middle, residual.end());
  // The median of |N(0, s)| is 0.6745 s; the residual's sigma is sqrt(1 + 4/16) of the pixels'.
  return *middle / 4.0 / 0.6745 / std::sqrt(1.25);
}

std::string noisy_reference_warning(const ImageU8& reference, const std::string& what) {
  const double noise = noise_levels(reference);
  if (!(noise > kNoisyReferenceLevels)) return "";
  char levels[32];
  std::snprintf(levels, sizeof levels, "%.1f", noise);
  return what + " holds camera noise of about " + levels +
         " levels (sigma, 0-255): every frame's difference to it carries that noise as well, "
         "which the normals network reads as dents in every contact (frames without contact "
         "are still told apart: noise changes no region as large as a press's). The per-pixel "
         "median of several frames without contact is quieter (about 1.25 x noise / sqrt(n): a "
         "dozen or more at sigma 7): patchgraph recording --background A.png B.png ... (files, "
         "videos or folders of them), or --background-frames FIRST-LAST for a recording's own "
         "frames before the touch";
}

double saturated_fraction(const ImageU8& image) {
  const std::size_t pixels = std::size_t(image.width) * image.height;
  if (pixels == 0 || image.channels < 1) return 0.0;
  // A normal has two tilts: a pixel needs two channels that can still change (one, in a grey
  // image).
  const auto needed = std::ptrdiff_t(std::min(image.channels, 2));
  std::size_t saturated = 0;
  for (std::size_t i = 0; i < pixels; ++i) {
    const std::uint8_t* p = &image.data[i * std::size_t(image.channels)];
    saturated += std::count_if(p, p + image.channels,
                               [](std::uint8_t v) { return v != 0 && v != 255; }) < needed;
  }
  return double(saturated) / double(pixels);
}

std::string saturated_reference_warning(const ImageU8& reference, const std::string& what) {
  const double saturated = saturated_fraction(reference);
  if (!(saturated > kSaturatedReferenceFraction)) return "";
  char percent[32];
  std::snprintf(percent, sizeof percent, "%.0f %%", 100 * saturated);
  return what + ": " + percent +
         " of its pixels are clipped (at most one colour channel between 0 and 255), where a "
         "press cannot show: the sensor is over- or under-exposed (its exposure, or its lights)";
}

std::vector<std::string> reference_warnings(const ImageU8& reference, const std::string& what) {
  std::vector<std::string> warnings;
  for (const std::string& warning :
       {noisy_reference_warning(reference, what), saturated_reference_warning(reference, what)}) {
    if (!warning.empty()) warnings.push_back(warning);
  }
  return warnings;
}

}  // namespace pg
