#include "allocation_counter.hpp"

#include <atomic>
#include <cstdlib>
#include <new>

// Kept in its own translation unit so that the replacement functions are never inlined into
// callers (GCC otherwise reports a malloc/delete mismatch it cannot see through).
namespace {
std::atomic<long> g_allocations{0};
}  // namespace

void* operator new(std::size_t size) {
  ++g_allocations;
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace hq::test {
long allocation_count() { return g_allocations.load(); }
}  // namespace hq::test
