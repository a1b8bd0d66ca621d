// The CPU backend's LargeVector allocator (sim/backend/cpu/huge_page_allocator.h): small arrays
// as before, large ones 2 MiB-aligned, and both hold and copy their values like std::vector.
#include "sim/backend/cpu/huge_page_allocator.h"

#include <gtest/gtest.h>

#include <cstdint>

#include "sim/backend/cpu/exec_cpu.h"

namespace gd::sim {
namespace {

TEST(HugePageAllocator, LargeArraysAreAlignedToTheHugePageAndHoldTheirValues) {
  using Large = CpuExec::LargeVector<double>;
  constexpr size_t kHuge = HugePageAllocator<double>::kHugePage;
  for (const size_t n : {size_t{10}, kHuge / sizeof(double) - 1, kHuge / sizeof(double), 3 * kHuge / sizeof(double) + 5}) {
    Large v;
    CpuExec::resize(v, n);
    ASSERT_EQ(v.size(), n);
    if (n * sizeof(double) >= kHuge) EXPECT_EQ(reinterpret_cast<std::uintptr_t>(v.data()) % kHuge, 0u) << n;
    for (size_t i = 0; i < n; ++i) EXPECT_EQ(v[i], 0.0) << i;
    for (size_t i = 0; i < n; ++i) v[i] = static_cast<double>(i);
    const Large copy = v;  // through the allocator again
    ASSERT_EQ(copy.size(), n);
    EXPECT_EQ(copy.back(), static_cast<double>(n - 1));
    EXPECT_EQ(CpuExec::ptr(copy)[n / 2], static_cast<double>(n / 2));
    v.resize(n + kHuge / sizeof(double));  // grows: moved to a new allocation, values kept
    EXPECT_EQ(v[n - 1], static_cast<double>(n - 1));
  }
}

}  // namespace
}  // namespace gd::sim
