#pragma once
// Test support: a private DDS domain per test process over loopback only, and waits that block
// on a waitset with a timeout (never sleep-poll).

#include "hq/link/link.hpp"
#include "hq/testing/loopback_dds.hpp"

#include <array>
#include <chrono>
#include <cstdlib>
#include <unistd.h>

namespace hq::link::test {

// Every discovered test runs in its own process (gtest_discover_tests); a pid-based domain id
// keeps parallel ctest runs, and other engineers' processes, from seeing each other's samples.
inline int private_domain_id() {
  static const int kDomainId = [] {
    hq::testing::use_loopback_dds();
    return hq::testing::private_domain_id(0);
  }();
  return kDomainId;
}

// Generous bound for anything that should happen at once on loopback; only a failure waits it.
inline constexpr dds_duration_t kPatience = DDS_SECS(5);

// Blocks until `reader` has a valid sample and takes it; false after `timeout`.
template <typename T>
bool take_within(const Participant& participant, Reader<T>& reader, T& sample,
                 dds_duration_t timeout = kPatience) {
  dds_sample_info_t info{};
  if (reader.take(sample, info)) return true;
  WaitSet waitset(participant);
  ReadCondition condition(reader);
  waitset.attach(condition.handle(), 1);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout);
  std::array<dds_attach_t, 1> triggered{};
  for (;;) {
    if (reader.take(sample, info)) return true;
    const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) return false;
    waitset.wait(triggered, left);
  }
}

// Blocks until `writer` matches at least `count` readers; false after `timeout`.
template <typename T>
bool wait_for_readers(const Participant& participant, Writer<T>& writer, std::uint32_t count,
                      dds_duration_t timeout = kPatience) {
  check(dds_set_status_mask(writer.handle(), DDS_PUBLICATION_MATCHED_STATUS), "dds_set_status_mask",
        "writer");
  WaitSet waitset(participant);
  waitset.attach(writer.handle(), 1);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout);
  std::array<dds_attach_t, 1> triggered{};
  while (writer.matched_readers() < count) {
    const auto left = std::chrono::duration_cast<std::chrono::nanoseconds>(
                          deadline - std::chrono::steady_clock::now())
                          .count();
    if (left <= 0) return false;
    waitset.wait(triggered, left);
    std::uint32_t status = 0;
    dds_take_status(writer.handle(), &status, DDS_PUBLICATION_MATCHED_STATUS);
  }
  return true;
}

}  // namespace hq::link::test
