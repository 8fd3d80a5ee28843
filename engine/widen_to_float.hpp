#pragma once
// Voxels of a file's stored type widened to the engine's floats, in parallel: a static_cast, as
// ITK's readers make it, except that a double beyond float's range becomes infinity (refused later
// as non-finite by validate_volume) rather than a conversion C++ leaves undefined.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstring>
#include <limits>
#include <type_traits>
#include <vector>

namespace fluoro {

// raw holds out.size() values of type T, at any alignment.
template <class T>
void widen_to_float(const void* raw, std::vector<float>& out) {
  const auto* bytes = static_cast<const unsigned char*>(raw);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, out.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      T v;
      std::memcpy(&v, bytes + i * sizeof(T), sizeof(T));
      if constexpr (std::is_same_v<T, double>) {
        constexpr double kMax = std::numeric_limits<float>::max();
        out[i] = v > kMax ? std::numeric_limits<float>::infinity()
                 : v < -kMax ? -std::numeric_limits<float>::infinity()
                             : static_cast<float>(v);
      } else {
        out[i] = static_cast<float>(v);
      }
    }
  });
}

}  // namespace fluoro
