#pragma once
// Where a colour frame differs from the sensor's no-contact reference beyond the camera's noise.
#include <cstdlib>
#include <string>
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

// Flood fill over a w x h grid from the pixels in `stack`: calls visit(j) for each 4-neighbour j
// of a filled pixel that accept(j) allows; visit must make accept(j) false for j (mark it), and
// j is filled next.
template <typename Accept, typename Visit>
void flood_fill(int w, int h, std::vector<int>& stack, Accept&& accept, Visit&& visit) {
  constexpr int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    const int x = i % w, y = i / w;
    for (int k = 0; k < 4; ++k) {
      const int nx = x + dx[k], ny = y + dy[k];
      if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
      const int j = ny * w + nx;
      if (!accept(j)) continue;
      visit(j);
      stack.push_back(j);
    }
  }
}

// The changed pixels of a frame (for_each_changed_pixel) as 4-connected regions.
struct ChangedRegions {
  std::vector<int> region;  // per pixel, row by row: its region's index, or -1 (unchanged)
  std::vector<int> sizes;   // per region, in the order their first pixels come row by row
  int changed = 0;          // changed pixels, in all regions

  // The largest region's index, or -1 when nothing changed.
  int largest() const;
  // The pixels in regions of at least `min_size` pixels.
  int pixels_in_regions_of(int min_size) const;
};
ChangedRegions changed_regions(const ImageU8& color, const ImageU8& reference);

// A region of fewer changed pixels than this is a speck, not a contact: the camera's noise
// clusters by the change test's 3x3 mean, and against one noisy frame as the reference (sigma 7
// in both) its largest clusters held 3-6 px in each of 19 frames without contact (up to 10 px in
// 2 of 400 in a review's scan), where the smallest contact region of the renders' frames (four
// benchmark sequences, the validation presses, the sphere press; 120x160) held 179 px. Specks are
// the camera's size, not the contact's, so this does not scale with the image; a user of it with
// a smaller least contact (a small image's) takes the smaller of the two.
constexpr int kSpeckPixels = 12;

// The changed pixels in regions larger than specks: of kSpeckPixels or more, or of the smallest
// contact `min_contact_pixels` where that is less (at 60x80 it is 5 px, whose changes may come
// in regions of 7, 4 and 3 px). A frame shows a contact when they are at least
// `min_contact_pixels` (the tracker's no-change test).
inline int pixels_beyond_specks(const ChangedRegions& changes, int min_contact_pixels) {
  return changes.pixels_in_regions_of(min_contact_pixels < kSpeckPixels ? min_contact_pixels
                                                                        : kSpeckPixels);
}

// The per-pixel and per-channel median of images of one size (of an even count, the two middle
// values' mean, rounded up): a no-contact reference from several frames. Not their mean: the
// camera's noise is clipped at 0 and 255, so where the gel saturates a channel the mean sits
// below the noise-free value, a brightness drift the network reads as slopes (eval-normals:
// contact angle 1.65 deg with the median of 15 frames, 2.98 with their mean, 2.83 with one frame,
// 1.68 with the noise-free image; docs/learned_normals.md). Throws std::invalid_argument for no
// images or images of different sizes.
ImageU8 median_image(const std::vector<ImageU8>& images);

// The camera noise an image carries, as a Gaussian sigma on the 0-255 scale: each pixel's
// difference from the mean of its four neighbours (sigma x 1.118 for white noise on a smooth
// image), by the median of its magnitude, so that the image's own edges hardly count. Measured:
// 0.3-1.0 on noise-free renders and on the real DIGIT background image, 6.3-7.0 on rendered frames
// with the renderer's sigma 7.
double noise_levels(const ImageU8& image);

// A no-contact reference noisier than this (noise_levels) makes trouble: with one frame of the
// renderer's sigma 7 as the reference, the difference images hold sigma 7 x sqrt 2, the change
// test above takes noise for contact and the network reads the reference's noise pattern as dents
// (20 of 20 frames without contact tracked as contact; docs/learned_normals.md). An audit saw it
// at sigma 6 and 7 and not at 2-5: the warning starts at 4, with a margin.
constexpr double kNoisyReferenceLevels = 4.0;

// "" when `reference` is no noisier than kNoisyReferenceLevels; else a warning naming `what`
// and how to get a quieter one.
std::string noisy_reference_warning(const ImageU8& reference, const std::string& what);

// The fraction of an image's pixels with at most one channel between 0 and 255 (the others
// clipped: white, black, or a light's colour alone), where a press cannot show: a normal's two
// tilts need two channels that can change (a grey image: its one channel). Measured: 0 % on the
// presets' synthetic backgrounds and the real DIGIT background (which clip single channels in up
// to 41 % of their pixels), 74 % or more on a sensor of two white lights whose presses label-ball
// mislabelled, 100 % with the light off or with one coloured light (a sensor file's `lights`
// replaces all three; that had counted 0 % when every channel had to be clipped).
double saturated_fraction(const ImageU8& image);
constexpr double kSaturatedReferenceFraction = 0.2;
// "" unless `reference` is saturated over more than kSaturatedReferenceFraction of it; else a
// warning naming `what`.
std::string saturated_reference_warning(const ImageU8& reference, const std::string& what);

// The warnings about a no-contact reference (`what` names it): noisy, or saturated over more
// than kSaturatedReferenceFraction of it.
std::vector<std::string> reference_warnings(const ImageU8& reference, const std::string& what);

}  // namespace pg
