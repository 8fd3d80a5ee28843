#pragma once
// An allocator whose vectors leave new elements default-initialised (for integers: unwritten)
// instead of zeroed. For buffers that are written in full right after they are sized, such as a
// resident volume's words: zeroing 100+ MB first costs a whole extra pass over memory and takes
// every page fault on one thread, before the parallel pass that writes them anyway. Large buffers
// also sit on huge pages (engine/huge_page_allocator.hpp): 512 times fewer page faults.
#include <memory>
#include <type_traits>
#include <utility>

#include "engine/huge_page_allocator.hpp"

namespace fluoro::cpu {

template <class T>
struct DefaultInitAllocator : HugePageAllocator<T> {
  using HugePageAllocator<T>::HugePageAllocator;
  template <class U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  template <class U>
  void construct(U* p) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

}  // namespace fluoro::cpu
