#include "hq/link/config.hpp"

#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace hq::link {
namespace {

using ::testing::HasSubstr;

LinkConfig from_yaml(const std::string& text) {
  config::StrictMap map(YAML::Load(text), "link.yaml", "link");
  LinkConfig config;
  read_config(map, config);
  return config;
}

TEST(LinkConfig, ReadsEveryKey) {
  const LinkConfig config = from_yaml(
      "{domain_id: 7, vehicle_id: 3, station_id: 9, station_strength: 250, "
      "command_deadline_ms: 50, command_lease_ms: 300, heartbeat_lease_ms: 2000, "
      "envelope: {max_v_x_mps: 1.5, max_v_y_mps: 1.25, max_v_z_mps: 0.5, "
      "max_yaw_rate_radps: 0.75}}");
  EXPECT_EQ(config.domain_id, 7);
  EXPECT_EQ(config.vehicle_id, 3u);
  EXPECT_EQ(config.station_id, 9u);
  EXPECT_EQ(config.station_strength, 250);
  EXPECT_EQ(config.command_deadline_ns, 50'000'000);
  EXPECT_EQ(config.command_lease_ns, 300'000'000);
  EXPECT_EQ(config.heartbeat_lease_ns, 2'000'000'000);
  EXPECT_EQ(config.envelope.max_v_x_mps, 1.5);
  EXPECT_EQ(config.envelope.max_v_y_mps, 1.25);
  EXPECT_EQ(config.envelope.max_v_z_mps, 0.5);
  EXPECT_EQ(config.envelope.max_yaw_rate_radps, 0.75);
}

TEST(LinkConfig, RejectsOutOfRangeDomainNamingFileKeyAndRange) {
  const std::string message =
      hq::testing::input_error_message([] { from_yaml("{domain_id: 300}"); });
  EXPECT_THAT(message, HasSubstr("link.yaml: link.domain_id = 300, expected in [0, 232]"));
}

TEST(LinkConfig, RejectsUnknownKey) {
  const std::string message = hq::testing::input_error_message([] { from_yaml("{domian_id: 3}"); });
  EXPECT_THAT(message, HasSubstr("domian_id"));
}

TEST(LinkConfig, RejectsNonPositiveEnvelopeAndTinyDeadline) {
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{envelope: {max_v_z_mps: 0}}"); }),
              HasSubstr("link.envelope.max_v_z_mps = 0, expected > 0"));
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{command_deadline_ms: 0.1}"); }),
              HasSubstr("link.command_deadline_ms = 0.1"));
}

TEST(LinkConfig, LoadsLinkSectionOfFile) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("hq_link_config_" + std::to_string(getpid()) + ".yaml");
  std::ofstream(path) << "other: {x: 1}\nlink: {vehicle_id: 4, station_strength: 10}\n";
  const LinkConfig config = load_link_config(path.string());
  std::filesystem::remove(path);
  EXPECT_EQ(config.vehicle_id, 4u);
  EXPECT_EQ(config.station_strength, 10);
  EXPECT_EQ(config.domain_id, 0);
}

// A --link-config whose link: section is misspelled used to fly on the defaults, exit 0.
TEST(LinkConfig, FileWithoutLinkSectionIsRejected) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() /
                                     ("hq_link_nosection_" + std::to_string(getpid()) + ".yaml");
  std::ofstream(path) << "lnik: {vehicle_id: 4}\n";
  EXPECT_THAT(hq::testing::input_error_message([&] { load_link_config(path.string()); }),
              HasSubstr(path.string() + ": link section missing, expected a `link:` mapping "
                                        "(top-level keys: lnik)"));
  std::filesystem::remove(path);
}

TEST(LinkConfig, CommandLineOverridesYaml) {
  LinkConfig config = from_yaml("{domain_id: 7, vehicle_id: 3, station_strength: 250}");
  CLI::App app;
  LinkOverrides overrides;
  add_link_options(app, overrides);
  std::vector<std::string> args = {"--command-deadline-ms", "40", "--station-strength", "90",
                                   "--domain-id",           "12"};
  std::reverse(args.begin(), args.end());  // CLI11 parses a reversed vector
  app.parse(args);
  apply_overrides(overrides, config);
  EXPECT_EQ(config.domain_id, 12);
  EXPECT_EQ(config.vehicle_id, 3u);  // not given: the file's value stays
  EXPECT_EQ(config.station_strength, 90);
  EXPECT_EQ(config.command_deadline_ns, 40'000'000);
}

// The stations allowed to command, from the file or --stations; 0 and junk refused.
TEST(LinkConfig, StationsFromYamlAndTheCommandLine) {
  EXPECT_TRUE(from_yaml("{}").stations.empty());  // any station
  LinkConfig config = from_yaml("{stations: [1, 4]}");
  EXPECT_EQ(config.stations, (std::vector<std::uint32_t>{1, 4}));
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{stations: [1, 0]}"); }),
              HasSubstr("link.stations[1] = 0"));
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{stations: 3}"); }),
              HasSubstr("link.stations = 3, expected a list"));
  CLI::App app;
  LinkOverrides overrides;
  add_link_options(app, overrides);
  std::vector<std::string> args = {"--stations", "2,7"};
  std::reverse(args.begin(), args.end());
  app.parse(args);
  apply_overrides(overrides, config);
  EXPECT_EQ(config.stations, (std::vector<std::uint32_t>{2, 7}));
}

TEST(LinkConfig, CommandLineRejectsOutOfRangeDomain) {
  CLI::App app;
  LinkOverrides overrides;
  add_link_options(app, overrides);
  std::vector<std::string> args = {"--domain-id", "999"};
  std::reverse(args.begin(), args.end());
  EXPECT_THROW(app.parse(args), CLI::ValidationError);
}

TEST(LinkConfig, CheckConfigNamesField) {
  LinkConfig config;
  config.command_lease_ns = 0;
  EXPECT_THAT(hq::testing::input_error_message([&] { check_config(config); }),
              HasSubstr("link.command_lease_ms = 0, expected in [1, 60000] ms"));
}

TEST(LinkConfig, ImpairmentFromYamlAndFromTheCommandLine) {
  LinkConfig config = from_yaml("{impair: {delay_ms: 40, loss: 0.01}}");
  EXPECT_EQ(config.impairment.delay_ms, 40.0);
  EXPECT_EQ(config.impairment.loss, 0.01);
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{impair: {loss: 1.5}}"); }),
              HasSubstr("link.impair.loss = 1.5"));
  CLI::App app;
  LinkOverrides overrides;
  add_link_options(app, overrides);
  std::vector<std::string> args = {"--link-impair", "delay_ms=150,jitter_ms=30,loss=0.05"};
  std::reverse(args.begin(), args.end());
  app.parse(args);
  apply_overrides(overrides, config);
  EXPECT_EQ(config.impairment.delay_ms, 150.0);
  EXPECT_EQ(config.impairment.jitter_ms, 30.0);
  EXPECT_EQ(config.impairment.loss, 0.05);
  overrides.link_impair = "loss=1.5";
  EXPECT_EQ(hq::testing::input_error_message([&] { apply_overrides(overrides, config); }),
            "--link-impair loss=1.5: expected 0..1");
}

TEST(LinkConfig, SecurityIsOnByDefaultAndReadFromYaml) {
  EXPECT_TRUE(LinkConfig{}.security.enabled);
  EXPECT_FALSE(LinkConfig{}.security.has_keys());
  const LinkConfig config = from_yaml(
      "{security: {keys_dir: keys, identity: station_2, permissions: p.p7s, "
      "library_dir: /opt/cyclone}}");
  EXPECT_TRUE(config.security.enabled);
  EXPECT_EQ(config.security.keys_dir, "keys");
  EXPECT_EQ(config.security.identity, "station_2");
  EXPECT_EQ(config.security.permissions, "p.p7s");
  EXPECT_EQ(config.security.library_dir, "/opt/cyclone");
  EXPECT_TRUE(config.security.has_keys());
  EXPECT_FALSE(from_yaml("{security: {enabled: false}}").security.enabled);
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{security: {key_dir: k}}"); }),
              HasSubstr("key_dir"));
}

TEST(LinkConfig, SecurityFromTheCommandLine) {
  {
    CLI::App app;
    LinkOverrides overrides;
    add_link_options(app, overrides);
    app.parse(std::vector<std::string>{"vehicle_1", "--identity", "keys", "--security-dir"});
    LinkConfig config;
    apply_overrides(overrides, config);
    EXPECT_EQ(config.security.keys_dir, "keys");
    EXPECT_EQ(config.security.identity, "vehicle_1");
    EXPECT_TRUE(config.security.enabled);
  }
  {
    CLI::App app;
    LinkOverrides overrides;
    add_link_options(app, overrides);
    app.parse(std::vector<std::string>{"--insecure"});
    LinkConfig config;
    apply_overrides(overrides, config);
    EXPECT_FALSE(config.security.enabled);
  }
  {
    CLI::App app;
    LinkOverrides overrides;
    add_link_options(app, overrides);
    app.parse(std::vector<std::string>{"keys", "--security-dir", "--insecure"});
    LinkConfig config;
    EXPECT_THAT(hq::testing::input_error_message([&] { apply_overrides(overrides, config); }),
                HasSubstr("--insecure: contradicts --security-dir"));
  }
}

}  // namespace
}  // namespace hq::link

namespace hq::link {
namespace {

LinkConfig with_args(LinkConfig config, std::vector<std::string> args) {
  CLI::App app;
  LinkOverrides overrides;
  add_link_options(app, overrides);
  std::reverse(args.begin(), args.end());  // CLI11 parses a reversed vector
  app.parse(args);
  apply_overrides(overrides, config);
  return config;
}

// ROS 2 topics are off unless asked for; the namespace defaults to hq<vehicle id>.
TEST(LinkConfig, Ros2IsOffByDefaultAndReadFromYaml) {
  const LinkConfig defaults = from_yaml("{vehicle_id: 4}");
  EXPECT_FALSE(defaults.ros2.enabled);
  EXPECT_EQ(ros2_namespace(defaults), "hq4");
  const LinkConfig config = from_yaml(
      "{security: {enabled: false}, ros2: {enabled: true, namespace: fleet/quad_2, "
      "station_id: 77}}");
  EXPECT_TRUE(config.ros2.enabled);
  EXPECT_EQ(ros2_namespace(config), "fleet/quad_2");
  EXPECT_EQ(config.ros2.station_id, 77u);
  EXPECT_NO_THROW(check_config(config));
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{ros2: {enable: true}}"); }),
              HasSubstr("enable"));
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{ros2: {station_id: 0}}"); }),
              HasSubstr("link.ros2.station_id = 0"));
}

// The record's ROS 2 bag is on by default (with or without the bridge) and can be turned off.
TEST(LinkConfig, Ros2RecordIsOnByDefaultAndReadStrictly) {
  EXPECT_TRUE(from_yaml("{vehicle_id: 4}").ros2.record);
  EXPECT_FALSE(from_yaml("{ros2: {record: false}}").ros2.record);
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{ros2: {record: maybe}}"); }),
              HasSubstr("record"));
  EXPECT_THAT(hq::testing::input_error_message([] { from_yaml("{ros2: {recrd: false}}"); }),
              HasSubstr("recrd"));
}

TEST(LinkConfig, Ros2NamespaceMustBeARosName) {
  for (const char* bad : {"/hq1", "hq1/", "1hq", "hq-1", "a//b", "hq 1", "a/2b"}) {
    LinkConfig config;
    config.ros2.ros_namespace = bad;
    EXPECT_THAT(hq::testing::input_error_message([&] { check_config(config); }),
                HasSubstr("link.ros2.namespace = \"" + std::string(bad) + "\""))
        << bad;
  }
  for (const char* good : {"hq1", "_x", "fleet/quad_2", "A/b9/_c"}) {
    LinkConfig config;
    config.ros2.ros_namespace = good;
    EXPECT_NO_THROW(check_config(config)) << good;
  }
}

// Security decision: ROS 2 topics need plain DDS; asking for both is refused with the reason.
TEST(LinkConfig, Ros2NeedsInsecureAndSaysWhy) {
  EXPECT_TRUE(with_args({}, {"--ros2", "--insecure"}).ros2.enabled);
  EXPECT_FALSE(with_args({}, {"--insecure"}).ros2.enabled);
  const std::string message = hq::testing::input_error_message([] { with_args({}, {"--ros2"}); });
  EXPECT_THAT(message, HasSubstr("link.ros2.enabled with DDS Security on"));
  EXPECT_THAT(message, HasSubstr("--insecure"));
}

// The ROS 2 station commands like any station: it must be allowed when link.stations is given.
TEST(LinkConfig, Ros2StationMustBeAnAllowedStation) {
  EXPECT_THAT(hq::testing::input_error_message([] {
                with_args({}, {"--ros2", "--insecure", "--stations", "1,2"});
              }),
              HasSubstr("link.ros2.station_id = 250, expected one of link.stations"));
  EXPECT_NO_THROW(with_args({}, {"--ros2", "--insecure", "--stations", "1,250"}));
}

}  // namespace
}  // namespace hq::link

namespace hq::link {
namespace {

// hq-ground used to accept --ros2 and --stations and ignore them.
TEST(LinkOptions, EachSideRefusesTheOtherSidesOptions) {
  const auto parses = [](LinkSide side, std::vector<std::string> args) {
    CLI::App app;
    LinkOverrides overrides;
    add_link_options(app, overrides, side);
    std::reverse(args.begin(), args.end());
    try {
      app.parse(args);
      return true;
    } catch (const CLI::ParseError&) {
      return false;
    }
  };
  EXPECT_FALSE(parses(LinkSide::kStation, {"--ros2"}));
  EXPECT_FALSE(parses(LinkSide::kStation, {"--stations", "1,2"}));
  EXPECT_TRUE(parses(LinkSide::kStation, {"--station-id", "2", "--station-strength", "3"}));
  EXPECT_FALSE(parses(LinkSide::kVehicle, {"--station-id", "2"}));
  EXPECT_FALSE(parses(LinkSide::kVehicle, {"--station-strength", "3"}));
  EXPECT_TRUE(parses(LinkSide::kVehicle, {"--ros2", "--stations", "1,2"}));
  EXPECT_TRUE(parses(LinkSide::kEither, {"--ros2", "--station-id", "2"}));
  for (LinkSide side : {LinkSide::kVehicle, LinkSide::kStation}) {
    EXPECT_TRUE(parses(side, {"--domain-id", "3", "--insecure", "--vehicle-id", "2"}));
  }
}

}  // namespace
}  // namespace hq::link
