// The pixel noise table (sim/src/shading.h): 8-bit samples of sigma * N(0, 1) in fixed-point
// steps, added to 16-bit fixed-point values in vector lanes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "shading.h"

namespace pg {
namespace {

constexpr std::size_t kFrame = 240 * 320 * 3;  // values in a 240x320 colour frame

// The table's samples in levels (0-255 scale): mean 0, standard deviation sigma, and tails out to
// the largest unit sample (about 5 sigma for 2^20 samples), for small and large sigma.
TEST(Noise, TableSamplesHaveTheConfiguredSigmaAndGaussianTails) {
  for (float sigma : {0.5f, 3.0f, 7.0f, 20.0f, 60.0f, 200.0f}) {
    const NoiseTable table(sigma);
    const double unit = double(table.step()) / double(1 << table.frac_bits());  // [levels]
    double sum = 0, sum_sq = 0, largest = 0;
    long beyond_2 = 0;
    for (std::int8_t s : table.samples()) {
      const double v = s * unit;
      sum += v;
      sum_sq += v * v;
      largest = std::max(largest, std::abs(v));
      beyond_2 += std::abs(v) > 2.0 * sigma;
    }
    const double n = double(table.samples().size());
    EXPECT_NEAR(sum / n, 0.0, 0.005 * sigma) << "sigma " << sigma;
    EXPECT_NEAR(std::sqrt(sum_sq / n), sigma, 0.003 * sigma) << "sigma " << sigma;
    EXPECT_GT(largest, 4.5 * sigma) << "sigma " << sigma;
    // P(|z| > 2) = 4.55%.
    EXPECT_NEAR(beyond_2 / n, 0.0455, 0.003) << "sigma " << sigma;
    // Fine steps: at most sigma / 20 (plus the 1/128-level grid of the values for small sigma).
    EXPECT_LE(unit, std::max(sigma / 20.0, 2.0 / 128.0)) << "sigma " << sigma;
  }
}

// Every output is the rounded, clamped sum of its value and the table sample at the seed's
// offset plus its position, whatever the run length (vector loops and their tails) and however a
// frame is cut in pieces; values near 0 and 255 exercise the clamping.
TEST(Noise, ApplyIsTheRoundedClampedSumInAnyPieces) {
  std::mt19937 rng(3);
  for (float sigma : {2.0f, 7.0f, 60.0f}) {
    const NoiseTable table(sigma);
    std::uniform_real_distribution<float> level(-1.0f, 256.0f);
    std::vector<std::int16_t> values(5000);
    for (auto& v : values) v = table.to_fixed(std::clamp(level(rng), 0.0f, 255.0f));
    const std::size_t size = table.samples().size();
    for (std::uint64_t seed : {1ull, 77ull, 123456789ull}) {
      std::vector<std::uint8_t> whole(values.size()), pieces(values.size());
      table.apply(values.data(), whole.data(), values.size(), seed, 1000);
      for (std::size_t i = 0, len = 1; i < values.size(); i += len, len = len * 2 + 3) {
        len = std::min(len, values.size() - i);
        table.apply(values.data() + i, pieces.data() + i, len, seed, 1000 + i);
      }
      EXPECT_EQ(whole, pieces) << "sigma " << sigma << " seed " << seed;
      const std::size_t offset = (std::size_t(splitmix64(seed)) + 1000) & (size - 1);
      const int bits = table.frac_bits(), half = (1 << bits) >> 1;
      for (std::size_t i = 0; i < values.size(); ++i) {
        const int s = table.samples()[(offset + i) & (size - 1)] * table.step();
        const int expected = std::clamp((values[i] + s + half) >> bits, 0, 255);
        ASSERT_EQ(int(whole[i]), expected) << "sigma " << sigma << " seed " << seed << " i " << i;
      }
    }
  }
}

// A frame of more values than the table (1024x1024 RGB: 3 Mi values, the table 1 Mi) reads each
// further table's length from another offset: wrapped around, channel c of pixel p had carried
// exactly the noise of channel c + 1 of pixel p + 349 525. Pieces still add up to the whole.
TEST(Noise, ALargeFrameDoesNotRepeatItsNoise) {
  const NoiseTable table(7.0f);
  const std::size_t size = table.samples().size();
  std::vector<std::int16_t> values(2 * size + 5000, table.to_fixed(128.0f));
  std::vector<std::uint8_t> whole(values.size()), pieces(values.size());
  table.apply(values.data(), whole.data(), values.size(), 42);
  for (std::size_t i = 0, len = 777; i < values.size(); i += len, len = len * 3 + 1) {
    len = std::min(len, values.size() - i);
    table.apply(values.data() + i, pieces.data() + i, len, 42, i);
  }
  EXPECT_EQ(whole, pieces);
  int repeated = 0;
  for (std::size_t i = 0; i < 5000; ++i) repeated += whole[i] == whole[i + size];
  EXPECT_LT(repeated, 500) << "of 5000 values, one table's length apart";  // ~4 % by chance
}

// A frame's noise: mean 0 and sigma (plus the rounding's 1/12) for small and large sigma, the same
// for the same seed, and uncorrelated with the next frame's.
TEST(Noise, FrameNoiseHasTheConfiguredSigmaAndIsFreshEachFrame) {
  for (float sigma : {0.5f, 3.0f, 7.0f, 20.0f}) {
    const NoiseTable table(sigma);
    const float clean = 127.3f;
    const std::vector<std::int16_t> values(kFrame, table.to_fixed(clean));
    std::vector<std::uint8_t> a(kFrame), b(kFrame), c(kFrame);
    table.apply(values.data(), a.data(), kFrame, 41);
    table.apply(values.data(), b.data(), kFrame, 41);
    table.apply(values.data(), c.data(), kFrame, 42);
    EXPECT_EQ(a, b);
    double sum = 0, sum_sq = 0, cross = 0;
    for (std::size_t i = 0; i < kFrame; ++i) {
      const double ea = a[i] - clean, ec = c[i] - clean;
      sum += ea;
      sum_sq += ea * ea;
      cross += ea * ec;
    }
    const double n = double(kFrame), var = sigma * sigma + 1.0 / 12.0;
    EXPECT_NEAR(sum / n, 0.0, 0.02 * sigma + 0.01) << "sigma " << sigma;
    EXPECT_NEAR(std::sqrt(sum_sq / n), std::sqrt(var), 0.01 * std::sqrt(var)) << "sigma " << sigma;
    // The clean value's fraction (0.3) biases each frame alike: compare with the mean removed.
    const double mean = sum / n;
    EXPECT_LT(std::abs(cross / n - mean * mean) / var, 0.02) << "sigma " << sigma;
  }
}

}  // namespace
}  // namespace pg
