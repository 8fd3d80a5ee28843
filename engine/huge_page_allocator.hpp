#pragma once
// An allocator that asks Linux for transparent huge pages (2 MiB) for large buffers: volumes,
// their resident voxel words, gradient fields.
//
// Why: such a buffer is touched page by page the first time it is written (zeroed by the vector,
// or filled by the volume's conversion), and with 4 KiB pages that is one page fault per 4 KiB:
// about 50,000 faults for a 256^3 CT and its resident words, 15 % of a whole `fluoro drr` run
// (docs/benchmarks.md). Debian's kernels default transparent huge pages to "madvise": a program
// gets them only for memory it marks with madvise(MADV_HUGEPAGE), which this allocator does.
// Buffers under kMinBytes keep the standard allocator (rounding them up to 2 MiB would waste
// memory). Elsewhere (other kernels, THP disabled) the advice is ignored and nothing changes.
#include <cstddef>
#include <cstdlib>
#include <memory>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace fluoro {

template <class T>
struct HugePageAllocator {
  using value_type = T;
  static constexpr size_t kPageBytes = size_t(2) << 20;
  static constexpr size_t kMinBytes = size_t(4) << 20;

  HugePageAllocator() noexcept = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}

  T* allocate(size_t n) {
    if (n > std::allocator_traits<std::allocator<T>>::max_size(std::allocator<T>())) throw std::bad_array_new_length();
    const size_t bytes = n * sizeof(T);
    if (bytes < kMinBytes) return std::allocator<T>().allocate(n);
    const size_t rounded = (bytes + kPageBytes - 1) / kPageBytes * kPageBytes;
    void* p = std::aligned_alloc(kPageBytes, rounded);
    if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    madvise(p, rounded, MADV_HUGEPAGE);  // advice only: a refusal leaves ordinary pages
#endif
    return static_cast<T*>(p);
  }
  void deallocate(T* p, size_t n) noexcept {
    if (n * sizeof(T) < kMinBytes) std::allocator<T>().deallocate(p, n);
    else std::free(p);
  }
};

template <class T, class U>
bool operator==(const HugePageAllocator<T>&, const HugePageAllocator<U>&) noexcept {
  return true;
}

}  // namespace fluoro
