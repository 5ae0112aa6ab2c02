#pragma once
/// Counts global operator new calls in this test binary, to show hot paths allocate nothing.

namespace hq::test {
long allocation_count();
}  // namespace hq::test
