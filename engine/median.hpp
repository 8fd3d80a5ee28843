#pragma once
// The median of a list of values, as the pipelines' robust estimates use it.
#include <algorithm>
#include <cstddef>
#include <vector>

namespace fluoro {

// The element at index n/2 of the sorted values (for an even count, the larger of the two middle
// ones); 0 for no values. Takes a copy, which nth_element reorders.
inline double upper_median(std::vector<double> v) {
  if (v.empty()) return 0;
  const std::ptrdiff_t h = std::ptrdiff_t(v.size() / 2);
  std::nth_element(v.begin(), v.begin() + h, v.end());
  return v[std::size_t(h)];
}

}  // namespace fluoro
