#pragma once
// A rectangle of pixels, half-open: x in [x0, x1), y in [y0, y1). May reach past the image (the
// Poisson window does); clip() keeps the part inside.
#include <algorithm>

namespace pg {

struct PixelBox {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;  // [px]

  int width() const { return x1 - x0; }
  int height() const { return y1 - y0; }
  bool empty() const { return x1 <= x0 || y1 <= y0; }
  long area() const { return empty() ? 0 : long(width()) * height(); }
  PixelBox clip(int image_width, int image_height) const {
    return {std::max(x0, 0), std::max(y0, 0), std::min(x1, image_width),
            std::min(y1, image_height)};
  }
};

}  // namespace pg
