#pragma once
/// \file
/// The allocator of the CPU backend's LargeVector (exec_cpu.h): arrays of megabytes that a scene
/// allocates once and streams through every iteration (the Hessian's blocks, the MAS
/// preconditioner's dense blocks and factors). From 2 MiB on, an allocation is aligned to 2 MiB,
/// rounded up to a multiple of it and marked for transparent huge pages (madvise MADV_HUGEPAGE,
/// which Linux honours in its default "madvise" mode) before anything touches it, so a pass over
/// it walks one TLB entry per 2 MiB instead of per 4 KiB: drape/20000 1.08x on one thread
/// (docs/physics.md, thirtieth round). Smaller ones come from operator new. Only for arrays that
/// live long: a huge page is zeroed whole at its first touch, and buffers reallocated every
/// Newton iteration paid that (glibc's hugetlb tunable for every allocation made fold/20000 slower).

#include <cstddef>
#include <cstdlib>
#include <new>

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace gd::sim {

template <class T>
struct HugePageAllocator {
  using value_type = T;
  /// Allocations of this size and more go on huge pages.
  static constexpr size_t kHugePage = size_t{2} << 20;

  HugePageAllocator() noexcept = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U>&) noexcept {}  // NOLINT: rebinding, as std::allocator

  T* allocate(size_t n) {
    const size_t bytes = n * sizeof(T);
    if (bytes < kHugePage) return static_cast<T*>(::operator new(bytes));
    const size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
    void* p = std::aligned_alloc(kHugePage, rounded);
    if (!p) throw std::bad_alloc();
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    madvise(p, rounded, MADV_HUGEPAGE);  // advice: without transparent huge pages, 4 KiB pages as before
#endif
    return static_cast<T*>(p);
  }

  void deallocate(T* p, size_t n) noexcept {
    if (n * sizeof(T) < kHugePage) {
      ::operator delete(p);
    } else {
      std::free(p);
    }
  }

  template <class U>
  bool operator==(const HugePageAllocator<U>&) const noexcept { return true; }
  template <class U>
  bool operator!=(const HugePageAllocator<U>&) const noexcept { return false; }
};

}  // namespace gd::sim
