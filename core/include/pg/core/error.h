#pragma once
// Error policy at the file/API boundary: an InputError names the file (and field) and what was
// expected. Tools catch it, print its message to stderr and exit 1.
#include <stdexcept>
#include <string>

namespace pg {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace pg
