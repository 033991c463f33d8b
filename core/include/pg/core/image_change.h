#pragma once
// Where a colour frame differs from the sensor's no-contact reference beyond the camera's noise.
#include <cstdlib>
#include <vector>

#include "pg/core/image.h"

namespace pg {

// A pixel has changed when the 3x3 mean of its difference to the reference exceeds
// kChangeLevels in some channel. The mean of nine pixels of noise sigma 7 (the renderer's) has a
// sigma of 2.3 levels, so 10 levels are 4.3 sigma: 0 or 1 such pixels in a rendered frame without
// contact, and none with less noise. A sphere pressed just deep enough for 6 pixels to be
// indented by 0.1 mm already changes 57 to 166 pixels by more, on the rigid and the elastic gel,
// with the synthetic and the real DIGIT background (docs/learned_normals.md). The mean reaches
// one pixel beyond a sharp change.
constexpr int kChangeLevels = 10;

// Calls visit(x, y) for each changed pixel (8-bit RGB images of one size; the image's outermost
// rows and columns are never visited), row by row, until it returns false.
template <typename Visit>
void for_each_changed_pixel(const ImageU8& color, const ImageU8& reference, Visit&& visit) {
  const std::size_t row = std::size_t(color.width) * 3;
  // Per row: the difference summed over it and the rows above and below, per column and
  // channel; then three of those sums side by side.
  std::vector<int> column(row);
  for (int y = 1; y + 1 < color.height; ++y) {
    const std::size_t above = std::size_t(y - 1) * row;
    for (std::size_t i = 0; i < row; ++i) {
      int sum = 0;
      for (std::size_t r = above; r < above + 3 * row; r += row) {
        sum += int(color.data[r + i]) - int(reference.data[r + i]);
      }
      column[i] = sum;
    }
    for (int x = 1; x + 1 < color.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const int sum = column[(x - 1) * 3 + c] + column[x * 3 + c] + column[(x + 1) * 3 + c];
        if (std::abs(sum) > 9 * kChangeLevels) {
          if (!visit(x, y)) return;
          break;
        }
      }
    }
  }
}

}  // namespace pg
