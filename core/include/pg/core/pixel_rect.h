#pragma once
// Half-open pixel rectangles [x0, x1) x [y0, y1): the regions the renderer and the tracker work
// on. May reach past the image (the tracker's Poisson window does); clipped() keeps the part
// inside.
#include <algorithm>

namespace pg {

struct PixelRect {
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;

  bool empty() const { return x1 <= x0 || y1 <= y0; }
  int width() const { return std::max(0, x1 - x0); }
  int height() const { return std::max(0, y1 - y0); }
  long area() const { return long(width()) * height(); }
  bool contains(int x, int y) const { return x >= x0 && x < x1 && y >= y0 && y < y1; }

  PixelRect dilated(int r) const { return {x0 - r, y0 - r, x1 + r, y1 + r}; }
  PixelRect clipped(int w, int h) const {
    return {std::max(x0, 0), std::max(y0, 0), std::min(x1, w), std::min(y1, h)};
  }
  PixelRect united(const PixelRect& o) const {
    if (empty()) return o;
    if (o.empty()) return *this;
    return {std::min(x0, o.x0), std::min(y0, o.y0), std::max(x1, o.x1), std::max(y1, o.y1)};
  }
  PixelRect intersected(const PixelRect& o) const {
    return {std::max(x0, o.x0), std::max(y0, o.y0), std::min(x1, o.x1), std::min(y1, o.y1)};
  }
  void include(int x, int y) { *this = united({x, y, x + 1, y + 1}); }
};

}  // namespace pg
