#include "hq/link/link.hpp"
#include "hq/link/test_support.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>

namespace hq::link {
namespace {

VelocityCommand command_from(std::uint32_t station_id, std::uint64_t sequence) {
  VelocityCommand command{};
  command.vehicle_id = 1;
  command.station_id = station_id;
  command.sequence_number = sequence;
  return command;
}

LinkConfig station_config(const LinkConfig& base, std::uint32_t station_id, int strength) {
  LinkConfig config = base;
  config.station_id = station_id;
  config.station_strength = strength;
  return config;
}

// GIVEN a primary (strength 200) and a backup (strength 100) station commanding vehicle 1.
// The configs are members initialised before the writers that use them (declaration order).
struct TwoStations {
  explicit TwoStations(const LinkConfig& base)
      : primary_config(station_config(base, 1, 200)), backup_config(station_config(base, 2, 100)) {}
  LinkConfig primary_config;
  LinkConfig backup_config;
  Participant vehicle{test::private_domain_id()};
  Participant primary_station{test::private_domain_id()};
  Participant backup_station{test::private_domain_id()};
  Topic<VelocityCommand> vehicle_topic{vehicle};
  Topic<VelocityCommand> primary_topic{primary_station};
  Topic<VelocityCommand> backup_topic{backup_station};
  Reader<VelocityCommand> reader{vehicle, vehicle_topic, command_qos(primary_config, End::kReader)};
  Writer<VelocityCommand> primary{primary_station, primary_topic,
                                  command_qos(primary_config, End::kWriter)};
  Writer<VelocityCommand> backup{backup_station, backup_topic,
                                 command_qos(backup_config, End::kWriter)};

  // Both write `rounds` commands alternately; returns how many of each the vehicle took.
  void exchange(int rounds, int& from_primary, int& from_backup) {
    VelocityCommand received{};
    for (std::uint64_t sequence = 0; sequence < static_cast<std::uint64_t>(rounds); ++sequence) {
      ASSERT_TRUE(primary.write(command_from(1, sequence)));
      ASSERT_TRUE(backup.write(command_from(2, sequence)));
      // The primary's command always follows; waiting for it also collects any backup one.
      while (test::take_within(vehicle, reader, received, DDS_MSECS(200))) {
        if (received.station_id == 1) ++from_primary;
        if (received.station_id == 2) ++from_backup;
        if (received.station_id == 1) break;
      }
    }
  }
};

TEST(Qos, ExclusiveOwnershipDeliversOnlyStrongestStationUntilItsWriterIsDeleted) {
  TwoStations stations(LinkConfig{});
  ASSERT_TRUE(test::wait_for_readers(stations.primary_station, stations.primary, 1));
  ASSERT_TRUE(test::wait_for_readers(stations.backup_station, stations.backup, 1));
  int from_primary = 0;
  int from_backup = 0;
  stations.exchange(20, from_primary, from_backup);
  EXPECT_GT(from_primary, 0);
  EXPECT_EQ(from_backup, 0);
  // WHEN the primary's writer goes away THEN the backup's commands arrive
  { Writer<VelocityCommand> gone(std::move(stations.primary)); }
  VelocityCommand received{};
  bool backup_arrived = false;
  for (std::uint64_t sequence = 0; sequence < 50 && !backup_arrived; ++sequence) {
    ASSERT_TRUE(stations.backup.write(command_from(2, 100 + sequence)));
    backup_arrived =
        test::take_within(stations.vehicle, stations.reader, received, DDS_MSECS(100)) &&
        received.station_id == 2;
  }
  EXPECT_TRUE(backup_arrived);
}

TEST(Qos, BackupTakesOverWhenPrimaryLivelinessLapses) {
  LinkConfig config;
  config.command_lease_ns = DDS_MSECS(200);
  TwoStations stations(config);
  ASSERT_TRUE(test::wait_for_readers(stations.primary_station, stations.primary, 1));
  ASSERT_TRUE(test::wait_for_readers(stations.backup_station, stations.backup, 1));
  int from_primary = 0;
  int from_backup = 0;
  stations.exchange(10, from_primary, from_backup);
  ASSERT_GT(from_primary, 0);
  ASSERT_EQ(from_backup, 0);
  // WHEN the primary stops writing (its writer still exists) THEN after its manual-by-topic lease
  // lapses the backup's commands arrive
  VelocityCommand received{};
  bool backup_arrived = false;
  for (std::uint64_t sequence = 0; sequence < 100 && !backup_arrived; ++sequence) {
    ASSERT_TRUE(stations.backup.write(command_from(2, 100 + sequence)));
    backup_arrived =
        test::take_within(stations.vehicle, stations.reader, received, DDS_MSECS(50)) &&
        received.station_id == 2;
  }
  EXPECT_TRUE(backup_arrived);
}

class DeadlineCounter : public StatusHandler {
 public:
  void on_requested_deadline_missed(dds_entity_t,
                                    const dds_requested_deadline_missed_status_t& status) override {
    const std::lock_guard lock(mutex_);
    total_count_ = status.total_count;
    changed_.notify_all();
  }
  bool wait_for_miss(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [this] { return total_count_ > 0; });
  }
  std::uint32_t total_count() {
    const std::lock_guard lock(mutex_);
    return total_count_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::uint32_t total_count_ = 0;
};

TEST(Qos, DeadlineMissedFiresWhenCommandsStop) {
  LinkConfig config;
  config.command_deadline_ns = DDS_MSECS(20);
  Participant vehicle(test::private_domain_id());
  Participant station(test::private_domain_id());
  Topic<VelocityCommand> vehicle_topic(vehicle);
  Topic<VelocityCommand> station_topic(station);
  DeadlineCounter counter;
  Listener listener(counter, DDS_REQUESTED_DEADLINE_MISSED_STATUS);
  Reader<VelocityCommand> reader(vehicle, vehicle_topic, command_qos(config, End::kReader),
                                 &listener);
  Writer<VelocityCommand> writer(station, station_topic, command_qos(config, End::kWriter));
  ASSERT_TRUE(test::wait_for_readers(station, writer, 1));
  // GIVEN an instance that has received a command (the deadline is per instance)
  ASSERT_TRUE(writer.write(command_from(1, 0)));
  VelocityCommand received{};
  ASSERT_TRUE(test::take_within(vehicle, reader, received));
  // WHEN nothing more is written THEN the deadline-missed callback fires
  EXPECT_TRUE(counter.wait_for_miss(std::chrono::seconds(5)));
  EXPECT_GT(counter.total_count(), 0u);
}

class LivelinessWatcher : public StatusHandler {
 public:
  void on_liveliness_changed(dds_entity_t, const dds_liveliness_changed_status_t& status) override {
    const std::lock_guard lock(mutex_);
    alive_ = status.alive_count;
    not_alive_changes_ += status.not_alive_count_change < 0 ? 0 : status.not_alive_count_change;
    changed_.notify_all();
  }
  bool wait_for_alive(std::uint32_t alive, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return alive_ == alive; });
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::uint32_t alive_ = 0;
  std::int32_t not_alive_changes_ = 0;
};

TEST(Qos, HeartbeatReaderSeesPeerWriterComeAndGo) {
  LinkConfig config;
  Participant vehicle(test::private_domain_id());
  Topic<Heartbeat> vehicle_topic(vehicle);
  LivelinessWatcher watcher;
  Listener listener(watcher, DDS_LIVELINESS_CHANGED_STATUS);
  Reader<Heartbeat> reader(vehicle, vehicle_topic, heartbeat_qos(config), &listener);
  {
    Participant station(test::private_domain_id());
    Topic<Heartbeat> station_topic(station);
    Writer<Heartbeat> writer(station, station_topic, heartbeat_qos(config));
    Heartbeat beat{};
    beat.vehicle_id = 1;
    ASSERT_TRUE(writer.write(beat));
    EXPECT_TRUE(watcher.wait_for_alive(1, std::chrono::seconds(5)));
  }
  EXPECT_TRUE(watcher.wait_for_alive(0, std::chrono::seconds(5)));
}

}  // namespace
}  // namespace hq::link
