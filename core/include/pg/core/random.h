#pragma once
// Seeded random numbers that are the same on every standard library: mt19937_64 with explicit
// mappings (the std:: distributions differ between implementations, and generated scene files
// must not).
#include <cstdint>
#include <random>

namespace pg {

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
