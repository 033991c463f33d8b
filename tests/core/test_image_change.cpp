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
  EXPECT_EQ(warnings[0].rfind("bg.png: 50 % of its pixels are clipped white or black", 0), 0u)
      << warnings[0];
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
