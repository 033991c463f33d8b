#pragma once
// PNG and EXR, the formats the project writes, read and written inside pg_core with libpng and
// OpenEXR: a program whose images are all PNG or EXR never loads the OpenImageIO module, whose
// libraries took about 0.45 s to load at the first image (image_codec.h). Other formats (JPEG,
// TIFF, ...) still go through the module. Each table follows image_codec::Table's contract: no
// exceptions, an empty string on success or the error's message naming the file.
#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "image_codec.h"

namespace pg::image_codec {

enum class Format { kOther, kPng, kExr };

// By the file's first bytes (a PNG named .exr is a PNG, as OpenImageIO read it); kOther for a
// file that cannot be opened, which the module then names.
Format format_of_file(const std::string& path);
// By the extension, case-insensitive: what a write of `path` makes.
Format format_of_name(const std::string& path);

const Table& png_table();
const Table& exr_table();

// Writes a file encoded in memory to `path` (replacing it): "" or the error naming the path,
// errno's value in error_number. One write where the encoders' own made many small ones.
std::string write_file(const std::string& path, const std::vector<std::uint8_t>& bytes,
                       int& error_number);

// Largest image read: width x height x channels values. A damaged header can claim any size.
inline constexpr long long kMaxImageValues = 1ll << 28;

// OpenImageIO's conversions, kept so that a file reads to the same values as before:
// an integer to float in [0, 1], times 1 / max; a float to an integer, scaled, rounded half away
// from zero and clamped (NaN: 0); an integer to a narrower one, through float, rounded.
template <typename T>
float unorm_to_float(T v) {
  return float(v) * (1.0f / float(std::numeric_limits<T>::max()));
}
template <typename T>
T float_to_unorm(float v) {
  const float max = float(std::numeric_limits<T>::max());
  float s = v * max;
  if (!(s == s)) return 0;
  s += s < 0.0f ? -0.5f : 0.5f;
  return T(std::clamp(s, 0.0f, max));
}
inline std::uint8_t u16_to_u8(std::uint16_t v) {
  return std::uint8_t(std::clamp(float(v) * (255.0f / 65535.0f) + 0.5f, 0.0f, 255.0f));
}

}  // namespace pg::image_codec
