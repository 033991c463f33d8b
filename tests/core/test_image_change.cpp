// The no-contact reference's helpers (pg/core/image_change.h): the median of several frames and
// the camera noise an image carries.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pg/core/image_change.h"

namespace pg {
namespace {

// A smooth shading (a gradient and a bump, as a gel's) with Gaussian noise of `sigma` levels,
// clipped and rounded as a camera's.
ImageU8 shaded(double sigma, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma);
  ImageU8 image(120, 160, 3);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double r2 = std::pow(x - 60.0, 2) + std::pow(y - 80.0, 2);
        const double value = 60 + 40 * c + 0.5 * x + 40 * std::exp(-r2 / 800) + noise(rng);
        image.at(x, y, c) = std::uint8_t(std::clamp(std::lround(value), 0L, 255L));
      }
    }
  }
  return image;
}

TEST(ImageChange, NoiseLevelsReadsTheCamerasSigma) {
  EXPECT_LT(noise_levels(shaded(0.0, 1)), 0.5);
  for (const double sigma : {2.0, 4.0, 7.0, 12.0}) {
    EXPECT_NEAR(noise_levels(shaded(sigma, 2)), sigma, 0.1 * sigma) << sigma;
  }
  EXPECT_EQ(noisy_reference_warning(shaded(2.0, 3), "x"), "");
  const std::string warning = noisy_reference_warning(shaded(7.0, 3), "bg.png");
  EXPECT_EQ(warning.rfind("bg.png holds camera noise of about 7", 0), 0u) << warning;
  EXPECT_EQ(reference_warnings(shaded(2.0, 3), "x").size(), 0u);
}

// An over-exposed reference (white over much of it) is warned about; one channel clipped, as
// the synthetic background's in places, is not.
TEST(ImageChange, ASaturatedReferenceIsWarnedAbout) {
  ImageU8 image = shaded(2.0, 4);
  for (std::size_t i = 0; i < image.data.size() / 2; i += 3) image.data[i] = 255;  // red
  EXPECT_EQ(saturated_fraction(image), 0.0);
  EXPECT_TRUE(reference_warnings(image, "bg.png").empty());
  for (std::size_t i = 0; i < image.data.size() / 2; ++i) image.data[i] = 255;  // white
  EXPECT_NEAR(saturated_fraction(image), 0.5, 0.01);
  const std::vector<std::string> warnings = reference_warnings(image, "bg.png");
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0].rfind("bg.png: 50 % of its pixels are clipped (at most one colour "
                              "channel between 0 and 255)",
                              0),
            0u)
      << warnings[0];
  // Two channels clipped leave one that changes, which cannot tell a normal's two tilts: one
  // coloured light, its other channels black. One channel clipped leaves two, enough.
  ImageU8 red = shaded(2.0, 4);
  for (std::size_t i = 0; i < red.data.size(); i += 3) red.data[i + 1] = red.data[i + 2] = 0;
  EXPECT_NEAR(saturated_fraction(red), 1.0, 1e-9);
  ImageU8 one = shaded(2.0, 4);
  for (std::size_t i = 0; i < one.data.size(); i += 3) one.data[i + 2] = 255;
  EXPECT_EQ(saturated_fraction(one), 0.0);
  // A grey image needs its one channel.
  ImageU8 grey(10, 10, 1, 128);
  EXPECT_EQ(saturated_fraction(grey), 0.0);
  for (std::size_t i = 0; i < 30; ++i) grey.data[i] = 255;
  EXPECT_NEAR(saturated_fraction(grey), 0.3, 1e-9);
}

// Changed pixels come in 4-connected regions: a press's disc is one, a touching corner another,
// a noisy reference's scattered changes are specks of a few pixels.
TEST(ImageChange, ChangedPixelsFormRegions) {
  const ImageU8 reference = shaded(0.0, 5);
  ImageU8 pressed = reference;
  const auto darken = [&](int x, int y) {
    for (int c = 0; c < 3; ++c) pressed.at(x, y, c) = std::uint8_t(pressed.at(x, y, c) / 2);
  };
  for (int y = 30; y < 50; ++y) {
    for (int x = 30; x < 50; ++x) {
      if (std::pow(x - 40, 2) + std::pow(y - 40, 2) <= 64) darken(x, y);  // a disc, radius 8
    }
  }
  for (int y = 120; y < 124; ++y) {
    for (int x = 90; x < 94; ++x) darken(x, y);  // a 4 x 4 square
  }
  const ChangedRegions changes = changed_regions(pressed, reference);
  ASSERT_EQ(changes.sizes.size(), 2u);
  // The 3x3 mean reaches a pixel beyond a sharp change: the disc's radius 9 or so, the square 6
  // x 6.
  EXPECT_NEAR(changes.sizes[0], 3.14159 * 81, 30);
  EXPECT_EQ(changes.sizes[1], 36);
  EXPECT_EQ(changes.largest(), 0);
  EXPECT_EQ(changes.changed, changes.sizes[0] + 36);
  EXPECT_EQ(changes.pixels_in_regions_of(37), changes.sizes[0]);
  EXPECT_EQ(changes.region[40 * 120 + 40], 0);
  EXPECT_EQ(changes.region[121 * 120 + 91], 1);
  EXPECT_EQ(changes.region[5 * 120 + 5], -1);
  int labelled = 0;
  for (const int r : changes.region) labelled += r >= 0;
  EXPECT_EQ(labelled, changes.changed);

  // One noisy frame against another (sigma 7 each): about a hundred changed pixels, in specks.
  const ChangedRegions noise = changed_regions(shaded(7.0, 6), shaded(7.0, 7));
  EXPECT_GT(noise.changed, 30);
  EXPECT_LT(noise.sizes[std::size_t(noise.largest())], kSpeckPixels);
  EXPECT_EQ(noise.pixels_in_regions_of(kSpeckPixels), 0);
  EXPECT_EQ(changed_regions(reference, reference).largest(), -1);
}

TEST(ImageChange, TheMedianOfFramesIsPerPixelAndQuieter) {
  ImageU8 a(2, 1, 1), b(2, 1, 1), c(2, 1, 1);
  a.data = {10, 200};
  b.data = {30, 0};
  c.data = {20, 100};
  EXPECT_EQ(median_image({a, b, c}).data, (std::vector<std::uint8_t>{20, 100}));
  EXPECT_EQ(median_image({a, b}).data, (std::vector<std::uint8_t>{20, 100}));  // mean, rounded up
  EXPECT_THROW(median_image({}), std::invalid_argument);
  EXPECT_THROW(median_image({a, ImageU8(1, 1, 1)}), std::invalid_argument);
  std::vector<ImageU8> frames;
  for (std::uint64_t seed = 10; seed < 26; ++seed) frames.push_back(shaded(7.0, seed));
  // The median of 16 frames: sigma 7 x 1.25 / 4, about 2.2.
  const double quiet = noise_levels(median_image(frames));
  EXPECT_LT(quiet, 3.0);
  EXPECT_GT(quiet, 1.5);
}

}  // namespace
}  // namespace pg
