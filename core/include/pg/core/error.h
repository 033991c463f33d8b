#pragma once
// Error policy at the file/API boundary: an InputError names the file (and field) and what was
// expected. Tools catch it, print its message to stderr and exit 1.
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>

namespace pg {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A combination of options that cannot run, found after parsing (one of two options that
// exclude each other must be given, say): tools exit 2, as for CLI11's own usage errors.
class UsageError : public InputError {
 public:
  using InputError::InputError;
};

// `text` as it may be quoted in a message: bytes outside printable ASCII as \xNN, and cut after
// `max_chars` characters with "...", so that a garbage file (a 2 MB binary "line") gives a short,
// printable message.
inline std::string excerpt(std::string_view text, std::size_t max_chars = 60) {
  std::string out;
  for (const char ch : text) {
    if (out.size() >= max_chars) return out + "...";
    const auto byte = static_cast<unsigned char>(ch);
    if (byte >= 0x20 && byte < 0x7f) {
      out += ch;
    } else {
      char hex[8];
      std::snprintf(hex, sizeof(hex), "\\x%02x", byte);
      out += hex;
    }
  }
  return out;
}

// Throws InputError "WHAT = VALUE: must be from LOW to HIGH" (followed by `also`, e.g. " (or 0:
// off)") unless low <= value <= high; a NaN is never in range.
inline void check_in_range(const std::string& what, double value, double low, double high,
                           const char* also = "") {
  if (value >= low && value <= high) return;
  char text[128];
  std::snprintf(text, sizeof text, " = %g: must be from %g to %g%s", value, low, high, also);
  throw InputError(what + text);
}

}  // namespace pg
