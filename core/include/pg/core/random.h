#pragma once
// Seeded random numbers that are the same on every standard library: mt19937_64 with explicit
// mappings (the std:: distributions differ between implementations, and generated scene files
// must not).
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>

#include "pg/core/numbers.h"

namespace pg {

// A uniform sample in (0, 1) from 64 random bits (their top 53): never 0, so its logarithm is
// finite.
inline double open_unit(std::uint64_t bits) { return (double(bits >> 11) + 0.5) * 0x1.0p-53; }

// Box-Muller: two independent standard normal samples from two uniform ones in (0, 1], written
// out so that every standard library gives the same.
inline std::pair<double, double> box_muller(double u1, double u2) {
  const double r = std::sqrt(-2.0 * std::log(u1)), a = 2.0 * kPi * u2;
  return {r * std::cos(a), r * std::sin(a)};
}

class Random {
 public:
  explicit Random(std::uint64_t seed) : engine_(seed) {}
  // Uniform in [lo, hi).
  double uniform(double lo, double hi) {
    return lo + (hi - lo) * double(engine_() >> 11) * 0x1.0p-53;
  }
  // Uniform in [lo, hi], lo <= hi (the modulo's bias is below range / 2^64, 2^-32 at most).
  int integer(int lo, int hi) {
    const std::uint64_t range = std::uint64_t(std::int64_t(hi) - std::int64_t(lo)) + 1;
    return int(std::int64_t(lo) + std::int64_t(engine_() % range));
  }
  double sign() { return (engine_() >> 63) ? 1.0 : -1.0; }

 private:
  std::mt19937_64 engine_;
};

}  // namespace pg
