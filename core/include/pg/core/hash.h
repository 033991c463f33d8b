#pragma once
// FNV-1a, 64 bits: a fast, stable hash of bytes for seeds and for telling files apart (not for
// security). The same on every platform and standard library.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

namespace pg {

inline constexpr std::uint64_t kFnvOffset = 0xcbf29ce484222325ull;

// FNV-1a of `n` bytes at `data`, continuing from `h` (kFnvOffset to start).
inline std::uint64_t fnv1a(const void* data, std::size_t n, std::uint64_t h = kFnvOffset) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) h = (h ^ bytes[i]) * 0x100000001b3ull;
  return h;
}
inline std::uint64_t fnv1a(std::string_view text, std::uint64_t h = kFnvOffset) {
  return fnv1a(text.data(), text.size(), h);
}

// `h` as 16 lower-case hex digits.
inline std::string hex64(std::uint64_t h) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
  return text;
}

}  // namespace pg
