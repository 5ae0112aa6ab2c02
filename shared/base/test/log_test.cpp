// The log layer: levels filter, lines keep their stream, and a logged line allocates nothing
// (so a 1 kHz loop's rare line costs no heap); likewise a text formatted into a fixed buffer.
#include "hq/base/log.hpp"

#include "hq/base/format_into.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <string>

namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// Counts every allocation of this test binary.
void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

namespace hq::log {
namespace {

class LogTest : public ::testing::Test {
 protected:
  void TearDown() override { set_level(Level::kInfo); }
};

TEST_F(LogTest, LevelsFilterAndStreamsAreKept) {
  set_level(Level::kWarning);
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  info("info {}\n", 1);
  note("note {}\n", 2);
  warn("warn {}\n", 3);
  error("error {}\n", 4);
  debug("debug {}\n", 5);
  EXPECT_EQ(::testing::internal::GetCapturedStdout(), "");
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "warn 3\nerror 4\n");

  set_level(Level::kDebug);
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  info("info {:.2f}\n", 1.0);
  note("note {}\n", "x");
  debug("debug {}\n", 5);
  EXPECT_EQ(::testing::internal::GetCapturedStdout(), "info 1.00\ndebug 5\n");
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "note x\n");
}

TEST_F(LogTest, ALoggedLineAllocatesNothing) {
  std::FILE* sink = std::fopen("/dev/null", "w");
  ASSERT_NE(sink, nullptr);
  write(Level::kInfo, sink, "warm-up {}\n", 0);  // stdio's own buffer, once per stream
  const long before = g_allocations.load();
  for (int i = 0; i < 1000; ++i) {
    write(Level::kInfo, sink, "t={:.3f} s v=({:.2f}, {:.2f}, {:.2f}) m/s status {} {}\n", 1e-3 * i,
          0.1, -0.2, 0.3, i, "tracking");
    debug("filtered {}\n", i);
  }
  const long after = g_allocations.load();
  std::fclose(sink);
  EXPECT_EQ(after - before, 0);
}

TEST(FormatInto, TruncatesLikeSnprintfAndAlwaysEndsTheText) {
  char text[8];
  EXPECT_EQ(hq::format_into(text, "{:.2f} m", 1.5), "1.50 m");
  EXPECT_STREQ(text, "1.50 m");
  EXPECT_EQ(hq::format_into(text, "station {} lost", 12), "station");
  EXPECT_STREQ(text, "station");
  char one[1] = {'x'};
  EXPECT_EQ(hq::format_into(one, "{}", 42), "");
  EXPECT_EQ(one[0], '\0');
  EXPECT_EQ(hq::format_into(nullptr, 0, "{}", 42), "");
}

TEST(FormatInto, AllocatesNothing) {
  char text[96];
  const long before = g_allocations.load();
  for (int i = 0; i < 1000; ++i) {
    hq::format_into(text, "no heartbeat from station {} for {:.1f} s: {}", i, 1e-3 * i, "landing");
  }
  EXPECT_EQ(g_allocations.load() - before, 0);
  EXPECT_STREQ(text, "no heartbeat from station 999 for 1.0 s: landing");
}

}  // namespace
}  // namespace hq::log
