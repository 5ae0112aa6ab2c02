#pragma once
/// Counts global operator new calls in a test binary that links hq::testing, so that a test can
/// show a hot path allocates nothing: `const long before = allocation_count(); ...;
/// EXPECT_EQ(allocation_count() - before, 0);`

namespace hq::testing {

/// Number of global operator new calls (all threads) since the program started.
long allocation_count();

}  // namespace hq::testing
