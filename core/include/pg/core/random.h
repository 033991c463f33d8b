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
  // Uniform in [lo, hi] (the modulo's bias is below 2^-40 for any int range).
  int integer(int lo, int hi) { return lo + int(engine_() % std::uint64_t(hi - lo + 1)); }
  double sign() { return (engine_() >> 63) ? 1.0 : -1.0; }

 private:
  std::mt19937_64 engine_;
};

}  // namespace pg
