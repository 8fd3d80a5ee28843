#pragma once
// Whole-volume scans of floats written so that they vectorise: one serial chain through every
// voxel (an accumulator such as `probe += x * 0`, or a running min) runs at one voxel per add
// latency, several times slower than the memory it reads.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

namespace fluoro {

// True when none of the n values is NaN or infinite (their exponent bits, tested as integers).
inline bool all_finite(const float* v, size_t n) {
  uint32_t special = 0;
  for (size_t i = 0; i < n; ++i) {
    uint32_t bits;
    std::memcpy(&bits, v + i, sizeof bits);
    special |= uint32_t((bits & 0x7f800000u) == 0x7f800000u);
  }
  return special == 0;
}

struct FloatRange {
  float min = std::numeric_limits<float>::infinity(), max = -std::numeric_limits<float>::infinity();
};

// The smallest and largest of n finite values (n = 0: +inf, -inf), in 16 independent lanes.
inline FloatRange finite_range(const float* v, size_t n) {
  constexpr size_t kLanes = 16;
  float lo[kLanes], hi[kLanes];
  std::fill(lo, lo + kLanes, std::numeric_limits<float>::infinity());
  std::fill(hi, hi + kLanes, -std::numeric_limits<float>::infinity());
  size_t i = 0;
  for (; i + kLanes <= n; i += kLanes)
    for (size_t l = 0; l < kLanes; ++l) {
      lo[l] = v[i + l] < lo[l] ? v[i + l] : lo[l];
      hi[l] = v[i + l] > hi[l] ? v[i + l] : hi[l];
    }
  for (; i < n; ++i) {
    lo[0] = std::min(lo[0], v[i]);
    hi[0] = std::max(hi[0], v[i]);
  }
  FloatRange r;
  for (size_t l = 0; l < kLanes; ++l) {
    r.min = std::min(r.min, lo[l]);
    r.max = std::max(r.max, hi[l]);
  }
  return r;
}

}  // namespace fluoro
