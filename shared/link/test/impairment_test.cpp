#include "hq/link/impairment.hpp"

#include "hq/link/link.hpp"
#include "hq/link/test_support.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>

namespace hq::link {
namespace {

using ::testing::HasSubstr;

TEST(Impairment, ParsesTheOptionAndRejectsBadValuesNamingKeyAndValue) {
  const ImpairmentConfig c = parse_impairment("delay_ms=150,jitter_ms=30,loss=0.05,seed=7");
  EXPECT_EQ(c.delay_ms, 150.0);
  EXPECT_EQ(c.jitter_ms, 30.0);
  EXPECT_EQ(c.loss, 0.05);
  EXPECT_EQ(c.seed, 7u);
  EXPECT_TRUE(c.active());
  EXPECT_FALSE(parse_impairment("").active());
  EXPECT_EQ(describe(c), "delay 150 ms, jitter +-30 ms, loss 5.0 %, seed 7");
  EXPECT_EQ(hq::testing::input_error_message([] { parse_impairment("loss=1.5"); }),
            "--link-impair loss=1.5: expected 0..1");
  EXPECT_THAT(hq::testing::input_error_message([] { parse_impairment("delay_ms=-3"); }),
              HasSubstr("--link-impair delay_ms=-3: expected 0..10000"));
  EXPECT_THAT(hq::testing::input_error_message([] { parse_impairment("delay_ms=fast"); }),
              HasSubstr("--link-impair delay_ms=fast: expected a number"));
  EXPECT_THAT(hq::testing::input_error_message([] { parse_impairment("lag_ms=3"); }),
              HasSubstr("unknown key 'lag_ms'"));
  EXPECT_THAT(hq::testing::input_error_message([] { parse_impairment("delay_ms"); }),
              HasSubstr("--link-impair delay_ms: expected key=value"));
}

TEST(Impairment, DropsAndDelaysAsConfiguredReproducibly) {
  ImpairmentConfig config;
  config.delay_ms = 150.0;
  config.jitter_ms = 30.0;
  config.loss = 0.05;
  Impairment a(config, 3);
  Impairment b(config, 3);
  int kept = 0;
  double min_ms = 1e9, max_ms = 0.0;
  for (int i = 0; i < 20000; ++i) {
    std::int64_t release_a = 0, release_b = 0;
    const bool keep_a = a.admit(1'000'000'000, release_a);
    const bool keep_b = b.admit(1'000'000'000, release_b);
    ASSERT_EQ(keep_a, keep_b);
    if (!keep_a) continue;
    ASSERT_EQ(release_a, release_b);
    ++kept;
    const double delay_ms = 1e-6 * static_cast<double>(release_a - 1'000'000'000);
    min_ms = std::min(min_ms, delay_ms);
    max_ms = std::max(max_ms, delay_ms);
  }
  EXPECT_NEAR(1.0 - kept / 20000.0, 0.05, 0.01);
  EXPECT_NEAR(static_cast<double>(a.dropped()) / static_cast<double>(a.received()), 0.05, 0.01);
  EXPECT_GE(min_ms, 120.0);
  EXPECT_LT(min_ms, 121.0);
  EXPECT_LE(max_ms, 180.0);
  EXPECT_GT(max_ms, 179.0);
}

TEST(Impairment, ReaderHandsSamplesOutLateAndDeepCopiesSequences) {
  // GIVEN a reader impaired by 100 ms +- 20 ms and 20 % loss, over loopback
  Participant participant(test::private_domain_id());
  Topic<VehicleState> topic(participant);
  Writer<VehicleState> writer(participant, topic, vehicle_state_qos());
  Reader<VehicleState> reader(participant, topic, vehicle_state_qos());
  reader.impair(parse_impairment("delay_ms=100,jitter_ms=20,loss=0.2,seed=5"), 1);
  Sample<VehicleState> sent;
  reserve(sent->obstacle_points_B_m, 3);
  sent->obstacle_points_B_m._length = 3;
  Sample<VehicleState> received;
  WaitSet waitset(participant);
  GuardCondition never(participant);
  waitset.attach(never.handle(), 1);
  std::array<dds_attach_t, 1> triggered{};
  int got = 0;
  double min_delay_ms = 1e9;
  constexpr int kSent = 40;
  for (int i = 1; i <= kSent; ++i) {
    sent->vehicle_id = 1;
    sent->sequence_number = static_cast<std::uint64_t>(i);
    sent->t_ns = dds_time();
    for (std::uint32_t p = 0; p < 3; ++p) {
      sent->obstacle_points_B_m._buffer[p] = {static_cast<float>(i), static_cast<float>(p), 0};
    }
    ASSERT_TRUE(writer.write(*sent));
    // WHEN the receiver polls every 5 ms (the waitset is the timer)
    waitset.wait(triggered, DDS_MSECS(5));
    dds_sample_info_t info{};
    while (reader.take(*received, info)) {
      ++got;
      min_delay_ms =
          std::min(min_delay_ms, 1e-6 * static_cast<double>(dds_time() - received->t_ns));
      // THEN the sequence arrives intact, not aliased to the ring's buffer
      ASSERT_EQ(received->obstacle_points_B_m._length, 3u);
      EXPECT_EQ(received->obstacle_points_B_m._buffer[2].x,
                static_cast<float>(received->sequence_number));
      EXPECT_EQ(received->obstacle_points_B_m._buffer[2].y, 2.0F);
    }
  }
  for (int i = 0; i < 40; ++i) {  // drain what is still in flight (200 ms)
    waitset.wait(triggered, DDS_MSECS(5));
    dds_sample_info_t info{};
    while (reader.take(*received, info)) {
      ++got;
      min_delay_ms =
          std::min(min_delay_ms, 1e-6 * static_cast<double>(dds_time() - received->t_ns));
    }
  }
  // ... no sample earlier than 80 ms, and about 20 % lost (8 of 40, seeded)
  EXPECT_GE(min_delay_ms, 80.0);
  EXPECT_EQ(static_cast<std::uint64_t>(got) + reader.impairment().dropped(),
            reader.impairment().received());
  EXPECT_GT(got, kSent / 2);
  EXPECT_LT(got, kSent);
}

}  // namespace
}  // namespace hq::link
