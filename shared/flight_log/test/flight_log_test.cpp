// The pieces both flight logs share: the bounded queue (order, drops counted, never blocking),
// the JSON builder (base64 as RFC 4648, NaN as null), and the link log with a local source:
// its channels, its queue drained by the log's thread, read back with hq::mcap::McapReader.
#include "hq/flight_log/json.hpp"
#include "hq/flight_log/link_log.hpp"
#include "hq/flight_log/spsc_queue.hpp"
#include "hq/flight_log/time_order.hpp"
#include "hq/mcap/mcap.hpp"
#include "hq/testing/allocation_counter.hpp"
#include "hq/testing/input_error.hpp"
#include "hq/testing/loopback_dds.hpp"

#include <dds/dds.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <sys/resource.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace hq::flight_log {
namespace {

namespace fs = std::filesystem;

struct Sample {
  std::int64_t t_ns = 0;
  double value = 0.0;
};

TEST(SpscQueue, DrainsInPushOrderAndCountsWhatAFullQueueRefuses) {
  SpscQueue<Sample> queue(4);
  for (int i = 0; i < 6; ++i) queue.push({i, 0.5 * i});
  EXPECT_EQ(queue.dropped(), 2u);
  std::vector<std::int64_t> seen;
  EXPECT_EQ(queue.drain([&](const Sample& s) { seen.push_back(s.t_ns); }), 4u);
  EXPECT_EQ(seen, (std::vector<std::int64_t>{0, 1, 2, 3}));
  EXPECT_TRUE(queue.push({7, 0}));  // slots freed by the drain
  seen.clear();
  queue.drain([&](const Sample& s) { seen.push_back(s.t_ns); });
  EXPECT_EQ(seen, (std::vector<std::int64_t>{7}));
}

TEST(SpscQueue, AProducerAndAConsumerThreadLoseNothingButWhatIsCounted) {
  SpscQueue<Sample> queue(64);
  constexpr int kPushed = 200'000;
  int refused = 0;
  std::atomic<bool> done{false};
  std::vector<std::int64_t> seen;
  seen.reserve(kPushed);
  std::thread consumer([&] {
    while (!done.load()) queue.drain([&](const Sample& s) { seen.push_back(s.t_ns); });
    queue.drain([&](const Sample& s) { seen.push_back(s.t_ns); });
  });
  for (int i = 0; i < kPushed; ++i) {
    if (!queue.push({i, 0})) ++refused;
  }
  done = true;
  consumer.join();
  EXPECT_EQ(seen.size() + static_cast<std::size_t>(refused), static_cast<std::size_t>(kPushed));
  EXPECT_EQ(queue.dropped(), static_cast<std::uint64_t>(refused));
  for (std::size_t i = 1; i < seen.size(); ++i) ASSERT_LT(seen[i - 1], seen[i]);
}

TEST(Json, Base64IsRfc4648WithPaddingAndNonFiniteIsNull) {
  Json j;
  const std::uint8_t text[] = {'f', 'o', 'o', 'b', 'a'};
  j.base64({text, 5});
  EXPECT_EQ(j.text(), "\"Zm9vYmE=\"");
  j.clear();
  j.base64({text, 4});
  EXPECT_EQ(j.text(), "\"Zm9vYg==\"");
  j.clear();
  j.number(NAN);
  j.raw(",");
  j.number(0.25);
  j.raw(",");
  j.stamp(3'000'000'007);
  j.raw(",");
  j.string("a\"b");
  EXPECT_EQ(j.text(), "null,0.25,{\"sec\":3,\"nsec\":7},\"a\\\"b\"");
}

// What the builder writes is JSON a real parser (nlohmann) reads back: float-exact numbers
// (%.9g), escaped quotes and backslashes, control characters left out, NaN and infinity as null.
TEST(Json, AParserReadsItBackFloatExact) {
  const std::array<float, 3> v = {0.1F, -1.17549435e-38F, 3.40282347e38F};
  Json j;
  j.raw("{\"timestamp\":");
  j.stamp(1'700'000'000'123'456'789);
  j.raw(",\"v\":");
  j.vector3(v);
  j.raw(",\"third\":");
  j.number(1.0F / 3.0F);
  j.raw(",\"inf\":");
  j.number(INFINITY);
  j.raw(",\"count\":");
  j.integer(-9'000'000'000'000'000'000LL);
  j.raw(",\"text\":");
  j.string("a \"quoted\" back\\slash\n");
  j.raw("}");
  const nlohmann::json parsed = nlohmann::json::parse(j.text(), nullptr, false);
  ASSERT_TRUE(parsed.is_object()) << j.text();
  EXPECT_EQ(parsed["timestamp"]["sec"], 1'700'000'000);
  EXPECT_EQ(parsed["timestamp"]["nsec"], 123'456'789);
  EXPECT_EQ(static_cast<float>(parsed["v"]["x"].get<double>()), v[0]);
  EXPECT_EQ(static_cast<float>(parsed["v"]["y"].get<double>()), v[1]);
  EXPECT_EQ(static_cast<float>(parsed["v"]["z"].get<double>()), v[2]);
  EXPECT_EQ(static_cast<float>(parsed["third"].get<double>()), 1.0F / 3.0F);
  EXPECT_TRUE(parsed["inf"].is_null());
  EXPECT_EQ(parsed["count"].get<std::int64_t>(), -9'000'000'000'000'000'000LL);
  EXPECT_EQ(parsed["text"], "a \"quoted\" back\\slash");
}

struct Released {
  std::uint16_t channel;
  std::int64_t log_ns;
  std::string text;
};

mcap::Bytes bytes_of(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

// GIVEN two queues whose stamps interleave (as a camera frame taken after the IMU samples of
// the same instant) WHEN added as they are drained THEN they come out oldest first, ties in
// arrival order, each with its own bytes, and only what the horizon passed.
TEST(TimeOrderBuffer, ReleasesInLogTimeOrderUpToTheHorizon) {
  TimeOrderBuffer order(64, 4096);
  std::vector<Released> out;
  const auto sink = [&](const TimeOrderBuffer::Message& m) {
    out.push_back({m.channel, m.log_ns, std::string(m.data.begin(), m.data.end())});
  };
  const std::string texts[] = {"a30", "a10", "b20", "b10", "c40"};
  order.add(1, 30, 30, bytes_of(texts[0]), sink);
  order.add(1, 10, 10, bytes_of(texts[1]), sink);
  order.add(2, 20, 20, bytes_of(texts[2]), sink);
  order.add(2, 10, 10, bytes_of(texts[3]), sink);
  order.add(3, 40, 40, bytes_of(texts[4]), sink);
  order.release(25, sink);
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[0].text, "a10");  // tie at 10: arrival order
  EXPECT_EQ(out[1].text, "b10");
  EXPECT_EQ(out[2].text, "b20");
  EXPECT_EQ(order.held(), 2u);
  order.release_all(sink);
  ASSERT_EQ(out.size(), 5u);
  EXPECT_EQ(out[3].text, "a30");
  EXPECT_EQ(out[4].text, "c40");
  EXPECT_EQ(out[4].channel, 3);
  EXPECT_EQ(order.late(), 0u);
}

// GIVEN a message older than one already released (held longer than the window) THEN it is
// released at that later time and counted, so the file's log times still never go back.
TEST(TimeOrderBuffer, ALateMessageIsRestampedToTheLastReleasedTimeAndCounted) {
  TimeOrderBuffer order(64, 4096);
  std::vector<Released> out;
  const auto sink = [&](const TimeOrderBuffer::Message& m) {
    out.push_back({m.channel, m.log_ns, std::string(m.data.begin(), m.data.end())});
  };
  const std::string text = "x";
  order.add(1, 100, 100, bytes_of(text), sink);
  order.release(150, sink);
  order.add(2, 70, 70, bytes_of(text), sink);
  order.release_all(sink);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[1].log_ns, 100);
  EXPECT_EQ(order.late(), 1u);
  EXPECT_EQ(order.late_max_ns(), 30);
}

// GIVEN more bytes than the buffer holds THEN the oldest are released early, still in order;
// and within its reserve, adding and releasing allocates nothing.
TEST(TimeOrderBuffer, FullReleasesTheOldestEarlyAndWithinItsReserveAllocatesNothing) {
  TimeOrderBuffer order(1000, 1000);
  std::vector<std::int64_t> released;
  released.reserve(1000);
  const auto sink = [&](const TimeOrderBuffer::Message& m) { released.push_back(m.log_ns); };
  const std::array<std::uint8_t, 100> payload{};
  for (int i = 0; i < 15; ++i) order.add(1, 1000 - i, 0, payload, sink);
  EXPECT_FALSE(released.empty());
  EXPECT_LE(order.held() * payload.size(), 1000u);
  order.release_all(sink);
  EXPECT_EQ(released.size(), 15u);
  EXPECT_TRUE(std::is_sorted(released.begin(), released.end()));

  const long before = hq::testing::allocation_count();
  for (int round = 0; round < 100; ++round) {
    for (int i = 0; i < 8; ++i) order.add(1, 10'000 + round * 10 + (7 - i), 0, payload, sink);
    order.release(10'000 + round * 10 + 4, sink);
  }
  EXPECT_EQ(hq::testing::allocation_count() - before, 0);
}

class CountingSource final : public LocalSource {
 public:
  void add_channels(ChannelWriter& out) override {
    channel_ = out.add_json_channel("/test/values", "test.Value",
                                    R"({"type":"object","properties":{"value":{}}})", {});
  }
  void drain(ChannelWriter& out) override {
    queue.drain([&](const Sample& s) {
      out.json().clear();
      out.json().raw("{\"value\":");
      out.json().number(s.value);
      out.json().raw("}");
      out.write_json(channel_, s.t_ns, s.t_ns);
    });
  }
  [[nodiscard]] std::uint64_t dropped() const override { return queue.dropped(); }
  [[nodiscard]] const char* dropped_key() const override { return "test_samples_dropped"; }

  SpscQueue<Sample> queue{4096};

 private:
  std::uint16_t channel_ = 0;
};

class LinkLogTest : public ::testing::Test {
 protected:
  void SetUp() override {
    hq::testing::use_loopback_dds();
    options_.link.domain_id = hq::testing::private_domain_id(31);
    options_.link.security.enabled = false;
    options_.role = security::Role::kVehicle;
    dir_ = fs::temp_directory_path() /
           ("hq_flight_log_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    options_.path = (dir_ / "log.mcap").string();
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  LinkLogOptions options_;
  fs::path dir_;
};

TEST_F(LinkLogTest, LocalSamplesAreWrittenOnTheLogsThreadWithTheLinkChannels) {
  CountingSource source;
  LinkLog log(options_, &source);
  constexpr int kSamples = 500;
  for (int i = 0; i < kSamples; ++i) source.queue.push({1'000'000'000 + i * 1'000'000, 0.5 * i});
  const RecorderReport& report = log.close({{"frames", "500"}});
  EXPECT_TRUE(report.error.empty()) << report.error;
  EXPECT_EQ(report.local_samples_dropped, 0u);

  const mcap::McapReader r(options_.path);
  std::vector<std::string> topics;
  for (const mcap::Channel& c : r.channels()) topics.push_back(c.topic);
  for (const char* topic :
       {"/hq/vehicle_state", "/hq/camera_frame", "/hq/event", "/hq/heartbeat",
        "/hq/velocity_command", "/hq/mode_request", "/obstacles", "/test/values"}) {
    EXPECT_NE(std::find(topics.begin(), topics.end(), topic), topics.end()) << topic;
  }
  ASSERT_EQ(r.messages().size(), static_cast<std::size_t>(kSamples));
  const mcap::Message& last = r.messages().back();
  EXPECT_EQ(std::string(last.data.begin(), last.data.end()), "{\"value\":249.5}");
  EXPECT_EQ(last.log_time_ns, 1'000'000'000 + (kSamples - 1) * 1'000'000);
  bool found = false;
  for (const mcap::Metadata& m : r.metadata()) {
    if (m.name == "recorder") {
      found = true;
      EXPECT_EQ(m.values.at("/test/values.messages"), "500");
      EXPECT_EQ(m.values.at("test_samples_dropped"), "0");
    }
    if (m.name == "flight_summary") {
      EXPECT_EQ(m.values.at("frames"), "500");
    }
  }
  EXPECT_TRUE(found);
}

// Two sources whose stamps interleave and arrive out of order (a second queue drained after
// the first, as the vehicle's IMU and step queues are): the file's log times never go back.
TEST_F(LinkLogTest, QueuesDrainedOneAfterAnotherAreWrittenInLogTimeOrder) {
  CountingSource source;
  options_.reorder_window_ns = 50'000'000;
  LinkLog log(options_, &source);
  constexpr int kSamples = 400;
  const std::int64_t now_ns = dds_time();
  for (int i = 0; i < kSamples; ++i) {
    // Two interleaved series pushed in the wrong order: odd stamps first, then even ones.
    const int k = i < kSamples / 2 ? 2 * i + 1 : 2 * (i - kSamples / 2);
    // Ahead of the clock, so they are all held until close whenever the thread drains.
    source.queue.push({now_ns + 1'000'000'000 + k * 100'000, 1.0 * k});
  }
  const RecorderReport& report = log.close();
  EXPECT_TRUE(report.error.empty()) << report.error;
  const mcap::McapReader r(options_.path);
  ASSERT_EQ(r.messages().size(), static_cast<std::size_t>(kSamples));
  for (std::size_t i = 1; i < r.messages().size(); ++i) {
    ASSERT_LE(r.messages()[i - 1].log_time_ns, r.messages()[i].log_time_ns) << i;
  }
  for (const mcap::Metadata& m : r.metadata()) {
    if (m.name == "recorder") {
      EXPECT_EQ(m.values.at("late_messages_restamped"), "0");
    }
  }
}

// GIVEN a log under way WHEN the disk fills (RLIMIT_FSIZE) THEN the report counts what the
// file holds (in total and per channel), the rest as not written, and names the failure.
TEST_F(LinkLogTest, FullDiskReportsTheMessagesInTheFileNotThoseHandedOver) {
  options_.writer.chunk_size_bytes = 16 * 1024;
  options_.writer.compression = mcap::Compression::kNone;
  CountingSource source;
  LinkLog log(options_, &source);
  rlimit saved{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &saved), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit limited = saved;
  limited.rlim_cur = fs::file_size(options_.path) + 40 * 1024;
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limited), 0);
  constexpr int kSamples = 4000;
  for (int i = 0; i < kSamples; ++i)
    source.queue.push({1'000'000'000 + std::int64_t{i} * 1'000'000, 0.5 * i});
  const RecorderReport& report = log.close();
  ::setrlimit(RLIMIT_FSIZE, &saved);
  std::signal(SIGXFSZ, old_handler);
  EXPECT_NE(report.error.find("log.mcap: recording stopped: "), std::string::npos) << report.error;
  EXPECT_NE(report.error.find("File too large"), std::string::npos) << report.error;

  const mcap::McapReader r(options_.path);
  ASSERT_GT(r.messages().size(), 0u);
  ASSERT_LT(r.messages().size(), static_cast<std::size_t>(kSamples));
  EXPECT_EQ(report.messages, r.messages().size());
  std::uint64_t reported_per_channel = 0;
  for (const ChannelReport& c : report.per_channel) reported_per_channel += c.messages;
  EXPECT_EQ(reported_per_channel, r.messages().size());
  std::string per_channel;
  for (const ChannelReport& c : report.per_channel) {
    per_channel += c.topic + " " + std::to_string(c.messages) + "\n";
  }
  // Each sample is in the file, refused by the queue or counted as not written.
  EXPECT_EQ(report.messages + report.samples_not_written + report.local_samples_dropped,
            static_cast<std::uint64_t>(kSamples))
      << per_channel << report.samples_not_written;
}

TEST_F(LinkLogTest, UnwritableFolderIsAClearErrorNamingThePath) {
  options_.path = "/proc/hq_no_such_folder/log.mcap";
  CountingSource source;
  const std::string message =
      hq::testing::input_error_message([&] { LinkLog log(options_, &source); });
  EXPECT_NE(message.find("/proc/hq_no_such_folder/log.mcap"), std::string::npos) << message;
}

}  // namespace
}  // namespace hq::flight_log
