// DDS Security on the link, real Cyclone DDS on loopback with keys made by hq::security (the
// code of hq-keys) in a temp dir: a permitted station commands its vehicle; nobody else delivers
// a single command, and a station cannot publish vehicle state.
#include "hq/link/test_support.hpp"
#include "hq/link/writer_binding.hpp"
#include "hq/security/keys.hpp"
#include "hq/testing/input_error.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <arpa/inet.h>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fmt/format.h>
#include <linux/if_packet.h>
#include <net/ethernet.h>
#include <net/if.h>
#include <optional>
#include <span>
#include <string>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>
#include <utility>
#include <vector>

namespace hq::link {
namespace {

using security::Role;

// The command every test station sends: x = 0.25 m/s, and y, z unlikely to occur by chance in
// anything else on the wire (the encryption test looks for these 12 bytes).
constexpr hq_msgs_Vector3f kMarker{0.25f, -1.2345678f, 3.1415927f};

// Nothing reaches an unauthorised reader "within a couple of seconds": on loopback a permitted
// sample arrives in milliseconds once matched, so this bounds the wait for the negative cases.
constexpr dds_duration_t kNothingWithin = DDS_SECS(2);

std::int64_t now_s() { return static_cast<std::int64_t>(std::time(nullptr)); }

class Secured : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        (std::filesystem::temp_directory_path() / ("hq_link_security_" + std::to_string(getpid())))
            .string();
    std::filesystem::remove_all(dir_);
    security::make_ca(dir_, security::valid_for_days(now_s(), 1));
    security::make_governance(dir_, security::DomainRange{});
    make(Role::kVehicle, 1, {});
    make(Role::kStation, 1, {1});
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  void make(Role role, std::uint32_t id, std::vector<std::uint32_t> vehicles,
            const std::string& dir = "", std::int64_t start_s = 0, std::int64_t end_s = 0) {
    security::IdentityRequest request;
    request.role = role;
    request.id = id;
    request.vehicles = std::move(vehicles);
    request.validity =
        start_s == 0 ? security::valid_for_days(now_s(), 1) : security::Validity{start_s, end_s};
    security::make_identity(dir.empty() ? dir_ : dir, request);
  }

  LinkConfig config(const std::string& keys_dir, const std::string& identity = "") const {
    LinkConfig c;
    c.domain_id = test::private_domain_id();
    c.vehicle_id = 1;
    c.station_id = 1;
    c.security.keys_dir = keys_dir.empty() ? dir_ : keys_dir;
    c.security.identity = identity;
    return c;
  }

  // A station commanding vehicle 1 (v_H.x = 0.25 m/s every 20 ms for `seconds`) in a child
  // process. Forked before this process touches DDS (Cyclone's threads do not survive fork),
  // and a process of its own because Cyclone's access-control plugin keeps one local
  // permissions per domain and process: one identity per process, as hq-onboard and hq-ground.
  // Exit status 0 when it commanded, 3 when it could not create its participant or writer.
  static pid_t spawn_station(const LinkConfig& c, double seconds, std::uint32_t claimed = 1) {
    const pid_t pid = fork();
    if (pid != 0) return pid;
    int code = 0;
    try {
      Participant station(c, Role::kStation);
      Topics topics(station);
      Writer<VelocityCommand> writer(station, topics.command, command_qos(c, End::kWriter));
      VelocityCommand command{};
      command.vehicle_id = 1;
      command.station_id = claimed;
      command.v_H_mps = kMarker;
      const std::int64_t end_ns = dds_time() + static_cast<std::int64_t>(seconds * 1e9);
      while (dds_time() < end_ns) {
        writer.write(command);
        dds_sleepfor(DDS_MSECS(20));
      }
    } catch (const std::exception& e) {
      fmt::print(stderr, "station: {}\n", e.what());
      code = 3;
    }
    std::_Exit(code);
  }

  static int exit_code(pid_t pid) {
    int status = 0;
    if (waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
    return WEXITSTATUS(status);
  }

  // Whether vehicle 1 (secured as vehicle_1 unless `c` says otherwise) takes a command within
  // `within`; `during` runs once the vehicle's reader exists (so the station sends).
  template <typename During = void (*)()>
  bool vehicle_takes_a_command(
      dds_duration_t within, std::optional<LinkConfig> plain = {}, During during = [] {}) const {
    const LinkConfig c = plain ? *plain : config("");
    Participant vehicle(c, Role::kVehicle);
    EXPECT_EQ(vehicle.secured(), !plain);
    Topics topics(vehicle);
    Reader<VelocityCommand> commands(vehicle, topics.command, command_qos(c, End::kReader));
    during();
    VelocityCommand got{};
    return test::take_within(vehicle, commands, got, within) && got.v_H_mps.x == 0.25f;
  }

  // The first command vehicle 1 takes within `within`: its claimed station id, and the station
  // the vehicle's WriterBinding finds behind its writer. Nullopt if none arrived.
  std::optional<std::pair<std::uint32_t, WriterStation>> command_and_its_writer(
      dds_duration_t within) const {
    const LinkConfig c = config("");
    Participant vehicle(c, Role::kVehicle);
    Topics topics(vehicle);
    Reader<VelocityCommand> commands(vehicle, topics.command, command_qos(c, End::kReader));
    WriterBinding writers(vehicle.secured(), c.vehicle_id);
    const std::int64_t end_ns = dds_time() + within;
    VelocityCommand got{};
    dds_sample_info_t info{};
    while (dds_time() < end_ns) {
      if (commands.take(got, info)) {
        return std::pair{got.station_id, writers.station_of(commands.handle(), info)};
      }
      dds_sleepfor(DDS_MSECS(10));
    }
    return std::nullopt;
  }

  std::string dir_;
};

TEST_F(Secured, PermittedStationCommandsItsVehicle) {
  const pid_t station = spawn_station(config(""), 2.5);
  ASSERT_GT(station, 0);
  // Within the window the refused stations below get: their silence is not a slow handshake.
  EXPECT_TRUE(vehicle_takes_a_command(kNothingWithin));
  EXPECT_EQ(exit_code(station), 0);
}

TEST_F(Secured, PlainStationDeliversNothing) {
  LinkConfig plain = config("");
  plain.security.enabled = false;
  const pid_t station = spawn_station(plain, 2.5);
  ASSERT_GT(station, 0);
  EXPECT_FALSE(vehicle_takes_a_command(kNothingWithin));
  EXPECT_EQ(exit_code(station), 0);  // it wrote, to nobody
}

TEST_F(Secured, StationOfAnotherCaDeliversNothing) {
  const std::string other = dir_ + "/other_ca";
  security::make_ca(other, security::valid_for_days(now_s(), 1));
  security::make_governance(other, security::DomainRange{});
  make(Role::kStation, 1, {1}, other);
  const pid_t station = spawn_station(config(other), 2.5);
  ASSERT_GT(station, 0);
  EXPECT_FALSE(vehicle_takes_a_command(kNothingWithin));
  EXPECT_EQ(exit_code(station), 0);  // its own CA vouches for it; ours does not
}

TEST_F(Secured, StationListedForAnotherVehicleDeliversNothing) {
  make(Role::kStation, 2, {2});  // station_2 may command vehicle 2 only
  LinkConfig other = config("", "station_2");
  other.station_id = 2;
  const pid_t station = spawn_station(other, 2.5);
  ASSERT_GT(station, 0);
  EXPECT_FALSE(vehicle_takes_a_command(kNothingWithin));
  EXPECT_EQ(exit_code(station), 3);  // its writer in vehicle 1's partition is refused
}

TEST_F(Secured, StationCannotCreateAWriterItIsNotGranted) {
  make(Role::kStation, 2, {2});
  LinkConfig other = config("", "station_2");
  other.station_id = 2;
  Participant station(other, Role::kStation);
  Topics topics(station);
  const std::string message = testing::input_error_message([&] {
    Writer<VelocityCommand> writer(station, topics.command, command_qos(other, End::kWriter));
  });
  EXPECT_NE(message.find("dds_create_writer(hq_velocity_command): Not Allowed By Security"),
            std::string::npos)
      << message;
}

// GIVEN station_3 listed for vehicle 1 like station_1, WHEN it writes commands claiming
// station 1, THEN the vehicle learns they come from station_3's certificate (its Failsafe then
// refuses the claim: failsafe_test), while station_1's own commands are bound to station 1.
TEST_F(Secured, VehicleKnowsWhichStationsCertificateWroteEachCommand) {
  make(Role::kStation, 3, {1});
  LinkConfig three = config("", "station_3");
  three.station_id = 3;
  pid_t station = spawn_station(three, 2.5, 1);
  ASSERT_GT(station, 0);
  auto seen = command_and_its_writer(kNothingWithin);
  EXPECT_EQ(exit_code(station), 0);
  ASSERT_TRUE(seen.has_value());
  EXPECT_EQ(seen->first, 1U);  // the claim
  EXPECT_TRUE(seen->second.bound);
  EXPECT_EQ(seen->second.station_id, 3U);  // the certificate

  station = spawn_station(config(""), 2.5, 1);
  ASSERT_GT(station, 0);
  seen = command_and_its_writer(kNothingWithin);
  EXPECT_EQ(exit_code(station), 0);
  ASSERT_TRUE(seen.has_value());
  EXPECT_TRUE(seen->second.bound);
  EXPECT_EQ(seen->second.station_id, 1U);

  // Plain DDS binds nothing: there is no certificate to ask.
  EXPECT_FALSE(WriterBinding(false, 1).station_of(0, dds_sample_info_t{}).bound);
}

// A station certified as station_3 that is told it is station 1 (hq-ground --identity
// station_3 --station-id 1) cannot even create its writers: station 1's partition is not in its
// grant, and the error says which certificate, which partitions and what to check.
TEST_F(Secured, StationCannotWriteInAnotherStationsPartition) {
  make(Role::kStation, 3, {1});
  LinkConfig three = config("", "station_3");
  three.station_id = 1;
  Participant station(three, Role::kStation);
  Topics topics(station);
  const std::string message = testing::input_error_message([&] {
    Writer<VelocityCommand> writer(station, topics.command, command_qos(three, End::kWriter));
  });
  EXPECT_NE(message.find("Not Allowed By Security"), std::string::npos) << message;
  EXPECT_NE(message.find(dir_ + "/station_3/cert.pem"), std::string::npos) << message;
  EXPECT_NE(message.find("hq_vehicle_1_station_1"), std::string::npos) << message;
  EXPECT_NE(message.find("is station_id 1 this certificate's station"), std::string::npos)
      << message;
}

TEST_F(Secured, StationCannotPublishVehicleState) {
  const LinkConfig c = config("");
  Participant station(c, Role::kStation);
  Topics topics(station);
  EXPECT_NO_THROW(Writer<VelocityCommand>(station, topics.command, command_qos(c, End::kWriter)));
  const std::string message = testing::input_error_message(
      [&] { Writer<VehicleState> writer(station, topics.vehicle_state, vehicle_state_qos()); });
  EXPECT_NE(message.find("dds_create_writer(hq_vehicle_state): Not Allowed By Security"),
            std::string::npos)
      << message;
}

TEST_F(Secured, VehiclePublishesStateButNotCommands) {
  const LinkConfig c = config("");
  Participant vehicle(c, Role::kVehicle);
  Topics topics(vehicle);
  EXPECT_NO_THROW(Writer<VehicleState>(vehicle, topics.vehicle_state, vehicle_state_qos()));
  const std::string message = testing::input_error_message([&] {
    Writer<VelocityCommand> writer(vehicle, topics.command, command_qos(c, End::kWriter));
  });
  EXPECT_NE(message.find("Not Allowed By Security"), std::string::npos) << message;
}

// Every frame on the loopback interface, through a packet socket (needs CAP_NET_RAW).
class LoopbackCapture {
 public:
  LoopbackCapture() : fd_(::socket(AF_PACKET, SOCK_RAW, htons(ETH_P_ALL))) {
    if (fd_ < 0) return;
    sockaddr_ll address{};
    address.sll_family = AF_PACKET;
    address.sll_protocol = htons(ETH_P_ALL);
    address.sll_ifindex = static_cast<int>(if_nametoindex("lo"));
    timeval timeout{0, 50'000};
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout) != 0) {
      ::close(fd_);
      fd_ = -1;
    }
  }
  ~LoopbackCapture() {
    if (fd_ >= 0) ::close(fd_);
  }
  LoopbackCapture(const LoopbackCapture&) = delete;
  LoopbackCapture& operator=(const LoopbackCapture&) = delete;
  [[nodiscard]] bool open() const { return fd_ >= 0; }

  // Reads frames for `duration`; counts them and whether any holds `pattern`.
  void watch(std::span<const unsigned char> pattern, dds_duration_t duration) {
    std::vector<unsigned char> frame(65'536);
    const std::int64_t end_ns = dds_time() + duration;
    while (dds_time() < end_ns) {
      const ssize_t n = ::recv(fd_, frame.data(), frame.size(), 0);
      if (n <= 0) continue;
      ++frames;
      const auto last = frame.begin() + n;
      if (std::search(frame.begin(), last, pattern.begin(), pattern.end()) != last) seen = true;
    }
  }
  int frames = 0;
  bool seen = false;

 private:
  int fd_;
};

TEST_F(Secured, CommandPayloadIsEncryptedOnTheWire) {
  if (!LoopbackCapture().open()) GTEST_SKIP() << "no packet socket (needs CAP_NET_RAW)";
  std::array<unsigned char, sizeof kMarker> pattern{};
  std::memcpy(pattern.data(), &kMarker, sizeof kMarker);  // CDR little-endian, as on x86
  // Control: on plain DDS the capture does see the command's bytes.
  LinkConfig plain = config("");
  plain.security.enabled = false;
  for (const bool secured : {false, true}) {
    SCOPED_TRACE(secured ? "secured" : "plain");
    const pid_t station = spawn_station(secured ? config("") : plain, 2.5);
    ASSERT_GT(station, 0);
    LoopbackCapture capture;
    const bool taken = vehicle_takes_a_command(
        kNothingWithin, secured ? std::optional<LinkConfig>{} : std::optional<LinkConfig>{plain},
        [&] { capture.watch(pattern, DDS_MSECS(1500)); });
    EXPECT_TRUE(taken);  // the station did send while we watched
    EXPECT_GT(capture.frames, 10);
    EXPECT_EQ(capture.seen, !secured);
    EXPECT_EQ(exit_code(station), 0);
  }
}

TEST_F(Secured, ExpiredCertificateIsRefusedNamingTheFile) {
  make(Role::kStation, 1, {1}, "", now_s() - 3 * 86'400, now_s() - 86'400);
  const std::string message =
      testing::input_error_message([&] { Participant station(config(""), Role::kStation); });
  EXPECT_NE(message.find(dir_ + "/station_1/cert.pem"), std::string::npos) << message;
  EXPECT_NE(message.find("expired"), std::string::npos) << message;
}

TEST_F(Secured, MissingOrMismatchedFilesAreNamed) {
  LinkConfig c = config("");
  c.security.private_key = dir_ + "/vehicle_1/key.pem";  // the vehicle's key for the station
  std::string message =
      testing::input_error_message([&] { Participant station(c, Role::kStation); });
  EXPECT_NE(message.find(dir_ + "/vehicle_1/key.pem"), std::string::npos) << message;
  EXPECT_NE(message.find("does not match the certificate"), std::string::npos) << message;

  c = config("", "station_9");
  message = testing::input_error_message([&] { Participant station(c, Role::kStation); });
  EXPECT_NE(message.find(dir_ + "/station_9/cert.pem"), std::string::npos) << message;
  EXPECT_NE(message.find("missing"), std::string::npos) << message;
}

TEST_F(Secured, DomainAboveWhatAccessControlAcceptsIsNamed) {
  LinkConfig c = config("");
  c.domain_id = 231;
  const std::string message =
      testing::input_error_message([&] { Participant vehicle(c, Role::kVehicle); });
  EXPECT_NE(message.find("link.domain_id = 231: a secured link needs a domain in [0, 230]"),
            std::string::npos)
      << message;
}

TEST_F(Secured, SecurityOnWithoutKeysTellsHowToMakeThem) {
  LinkConfig c;
  c.domain_id = test::private_domain_id();
  const std::string message =
      testing::input_error_message([&] { Participant vehicle(c, Role::kVehicle); });
  EXPECT_NE(message.find("hq-keys identity KEYS --role vehicle --id 1"), std::string::npos)
      << message;
  EXPECT_NE(message.find("--insecure"), std::string::npos) << message;
}

}  // namespace
}  // namespace hq::link
