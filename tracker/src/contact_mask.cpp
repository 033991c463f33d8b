#include "pg/tracker/contact_mask.h"

#include <algorithm>
#include <cassert>
#include <vector>

namespace pg {

void contact_mask(const ImageF& depth, const PixelRect& window, const MaskOptions& options,
                  double pixel_area_m2, ContactMask& out) {
  assert(depth.channels == 1);
  const int W = depth.width, H = depth.height;
  if (!out.mask.same_shape(W, H, 1)) {
    out.mask = ImageU8(W, H, 1, 0);
  } else {
    const PixelRect old = out.box.clipped(W, H);
    for (int y = old.y0; y < old.y1; ++y) std::fill_n(&out.mask.at(old.x0, y), old.width(), 0);
  }
  const PixelRect win = window.clipped(W, H);
  // The relative threshold refers to a high percentile of the indented pixels rather than the
  // single deepest one, so that one outlier pixel cannot empty the mask.
  thread_local std::vector<float> indented;
  indented.clear();
  for (int y = win.y0; y < win.y1; ++y) {
    const float* u = &depth.at(0, y);
    for (int x = win.x0; x < win.x1; ++x) {
      if (u[x] > float(options.min_depth_m)) indented.push_back(u[x]);
    }
  }
  float deepest = 0.0f;
  if (!indented.empty()) {
    const auto k = indented.begin() + std::ptrdiff_t(0.98 * double(indented.size() - 1));
    std::nth_element(indented.begin(), k, indented.end());
    deepest = *k;
  }
  const float threshold = indentation_threshold(options, options.relative_depth, deepest);
  int pixels = 0, x0 = W, y0 = H, x1 = -1, y1 = -1;
  for (int y = win.y0; y < win.y1; ++y) {
    const float* u = &depth.at(0, y);
    std::uint8_t* m = &out.mask.at(0, y);
    for (int x = win.x0; x < win.x1; ++x) {
      if (u[x] > threshold) {
        m[x] = 255;
        ++pixels;
        x0 = std::min(x0, x);
        x1 = std::max(x1, x);
        y0 = std::min(y0, y);
        y1 = std::max(y1, y);
      }
    }
  }
  out.pixels = pixels;
  out.deepest_m = deepest;
  out.box = pixels > 0 ? PixelRect{x0, y0, x1 + 1, y1 + 1} : PixelRect{};
  out.area_m2 = pixels * pixel_area_m2;
  out.contact = pixels > 0 && out.area_m2 >= options.min_area_m2;
}

}  // namespace pg
