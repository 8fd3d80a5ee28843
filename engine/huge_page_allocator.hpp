#pragma once
// An allocator that asks Linux for transparent huge pages (2 MiB) for large buffers: volumes,
// their resident voxel words, gradient fields.
//
// Why: such a buffer is touched page by page the first time it is written (zeroed by the vector,
// or filled by the volume's conversion), and with 4 KiB pages that is one page fault per 4 KiB:
// about 50,000 faults for a 256^3 CT and its resident words, 15 % of a whole `fluoro drr` run
// (docs/benchmarks.md). Debian's kernels default transparent huge pages to "madvise": a program
// gets them only for memory it marks with madvise(MADV_HUGEPAGE), which this allocator does.
//
// Buffers of kMinBytes or more get a mapping of their own (mmap, aligned to 2 MiB, unmapped when
// freed), so the advice never outlives them: marking memory that malloc hands out again would
// leave its later small allocations on huge pages too. Smaller buffers keep the standard
// allocator (rounding them up to 2 MiB would waste memory). Under AddressSanitizer every buffer
// comes from the standard allocator, so the sanitizer still sees overflows of voxel buffers.
// Elsewhere (other kernels, THP disabled) the advice is ignored and nothing else changes.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <new>
#include <type_traits>

#if defined(__linux__)
#include <sys/mman.h>
#endif

#if defined(__SANITIZE_ADDRESS__)
#define FLUORO_OWN_MAPPINGS 0
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(memory_sanitizer)
#define FLUORO_OWN_MAPPINGS 0
#endif
#endif
#if !defined(FLUORO_OWN_MAPPINGS)
#if defined(__linux__)
#define FLUORO_OWN_MAPPINGS 1
#else
#define FLUORO_OWN_MAPPINGS 0
#endif
#endif

namespace fluoro {

template <class T>
struct HugePageAllocator {
  using value_type = T;
  using propagate_on_container_move_assignment = std::true_type;
  using is_always_equal = std::true_type;
  static constexpr size_t kPageBytes = size_t(2) << 20;
  static constexpr size_t kMinBytes = size_t(4) << 20;

  HugePageAllocator() noexcept = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}

  // Whether large buffers get mappings of their own here (not under sanitizers, Linux only).
  static constexpr bool kOwnMappings = FLUORO_OWN_MAPPINGS;

  T* allocate(size_t n) {
    // Room for the rounding and the alignment slack below without wrapping around.
    if (n > (size_t(PTRDIFF_MAX) - 2 * kPageBytes) / sizeof(T)) throw std::bad_array_new_length();
#if FLUORO_OWN_MAPPINGS
    if (n * sizeof(T) >= kMinBytes) {
      const size_t bytes = mapped_bytes(n);
      // Map one huge page more than needed, then unmap the unaligned head and the tail.
      void* raw = mmap(nullptr, bytes + kPageBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (raw == MAP_FAILED) throw std::bad_alloc();
      const uintptr_t start = reinterpret_cast<uintptr_t>(raw), end = start + bytes + kPageBytes;
      const uintptr_t aligned = (start + kPageBytes - 1) / kPageBytes * kPageBytes;
      if (aligned > start) munmap(raw, aligned - start);
      if (end > aligned + bytes) munmap(reinterpret_cast<void*>(aligned + bytes), end - (aligned + bytes));
#if defined(MADV_HUGEPAGE)
      madvise(reinterpret_cast<void*>(aligned), bytes, MADV_HUGEPAGE);  // advice only: a refusal leaves small pages
#endif
      return reinterpret_cast<T*>(aligned);
    }
#endif
    return std::allocator<T>().allocate(n);
  }
  void deallocate(T* p, size_t n) noexcept {
#if FLUORO_OWN_MAPPINGS
    if (n * sizeof(T) >= kMinBytes) {
      munmap(p, mapped_bytes(n));
      return;
    }
#endif
    std::allocator<T>().deallocate(p, n);
  }

 private:
  static constexpr size_t mapped_bytes(size_t n) { return (n * sizeof(T) + kPageBytes - 1) / kPageBytes * kPageBytes; }
};

template <class T, class U>
bool operator==(const HugePageAllocator<T>&, const HugePageAllocator<U>&) noexcept {
  return true;
}

}  // namespace fluoro
