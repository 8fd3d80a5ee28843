#pragma once
// Voxels of a file's stored type widened to the engine's floats, in parallel: a static_cast, as
// ITK's readers make it, except that a double beyond float's range becomes infinity (refused later
// as non-finite by validate_volume) rather than a conversion C++ leaves undefined. The volume
// readers that bypass ITK's image buffer (engine/nifti_header.hpp, engine/metaimage_header.hpp)
// share it, so every format converts a stored type the same way.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <type_traits>
#include <vector>

#include "engine/volume.hpp"  // VoxelBuffer, HugePageAllocator

namespace fluoro {

// The scalar types a volume file may store, in this machine's byte order.
enum class StoredType { u8, i8, i16, u16, i32, u32, i64, u64, f32, f64 };

constexpr int stored_type_bytes(StoredType t) {
  switch (t) {
    case StoredType::u8: case StoredType::i8: return 1;
    case StoredType::i16: case StoredType::u16: return 2;
    case StoredType::i32: case StoredType::u32: case StoredType::f32: return 4;
    case StoredType::i64: case StoredType::u64: case StoredType::f64: return 8;
  }
  return 0;
}

// raw holds `count` values of type T, at any alignment; out has room for as many floats.
// Isolated: a reader calls this holding the lock of its library capture (library_output.hpp), so
// while it waits this thread must not take another task of an outer parallel loop (a panorama's
// frames read in parallel), which would take that lock again and hang.
template <class T>
void widen_to_float(const void* raw, float* out, size_t count) {
  const auto* bytes = static_cast<const unsigned char*>(raw);
  tbb::this_task_arena::isolate([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1 << 16), [&](const tbb::blocked_range<size_t>& r) {
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
  });
}

// raw holds `count` values of type `type`; out has room for as many floats.
inline void widen_to_float(StoredType type, const void* raw, float* out, size_t count) {
  switch (type) {
    case StoredType::u8: widen_to_float<uint8_t>(raw, out, count); break;
    case StoredType::i8: widen_to_float<int8_t>(raw, out, count); break;
    case StoredType::i16: widen_to_float<int16_t>(raw, out, count); break;
    case StoredType::u16: widen_to_float<uint16_t>(raw, out, count); break;
    case StoredType::i32: widen_to_float<int32_t>(raw, out, count); break;
    case StoredType::u32: widen_to_float<uint32_t>(raw, out, count); break;
    case StoredType::i64: widen_to_float<int64_t>(raw, out, count); break;
    case StoredType::u64: widen_to_float<uint64_t>(raw, out, count); break;
    case StoredType::f32: widen_to_float<float>(raw, out, count); break;
    case StoredType::f64: widen_to_float<double>(raw, out, count); break;
  }
}

// The `count` voxels of `type` that fill(dst, bytes) stores at dst, as floats: a float file's
// straight into the floats (no second copy of a CT-sized buffer), any other type's through one
// buffer of the stored type.
template <class Fill>
VoxelBuffer read_widened(StoredType type, size_t count, Fill fill) {
  VoxelBuffer out(count);
  const size_t bytes = count * size_t(stored_type_bytes(type));
  if (type == StoredType::f32) {
    fill(reinterpret_cast<unsigned char*>(out.data()), bytes);
    return out;
  }
  HugePageAllocator<unsigned char> allocator;  // left unwritten until fill writes it
  const auto release = [&](unsigned char* p) { allocator.deallocate(p, bytes); };
  const std::unique_ptr<unsigned char, decltype(release)> buffer(allocator.allocate(bytes), release);
  fill(buffer.get(), bytes);
  widen_to_float(type, buffer.get(), out.data(), count);
  return out;
}

}  // namespace fluoro
