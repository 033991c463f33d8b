#pragma once
// Constants of the project's math, one definition each (M_PI is POSIX, not C++).

namespace pg {

inline constexpr double kPi = 3.14159265358979323846;

}  // namespace pg
