#pragma once
// Small summary statistics shared by the tools and the evaluation code.
#include <algorithm>
#include <vector>

namespace pg {

// The upper median: the element at index n/2 of the sorted values (for timings, where a value
// that was actually measured is wanted). Requires a non-empty vector.
inline double upper_median(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

}  // namespace pg
