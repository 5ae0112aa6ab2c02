#include "hq/mavlink/transport.hpp"

#include "hq/base/error.hpp"
#include "hq/mavlink/codec.hpp"
#include "hq/testing/input_error.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <fcntl.h>
#include <pty.h>
#include <string>
#include <termios.h>
#include <unistd.h>
#include <vector>

namespace hq::mavlink {
namespace {

using ::testing::HasSubstr;

// A port per test process, so engineers running the suite side by side do not collide.
int test_port(int offset) { return 20000 + static_cast<int>(::getpid() % 20000) + offset; }

std::vector<std::uint8_t> receive_within(Transport& t, std::int64_t timeout_ns) {
  std::array<std::uint8_t, 512> buffer{};
  if (!t.wait_readable(timeout_ns)) return {};
  const std::size_t n = t.receive(buffer);
  return {buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(n)};
}

TEST(Transport, UdpListenLearnsThePeerAndReplies) {
  const int port = test_port(0);
  auto server = open_transport("udp-listen:" + std::to_string(port));
  auto client = open_transport("udp:127.0.0.1:" + std::to_string(port));
  EXPECT_TRUE(server->datagrams());
  EXPECT_TRUE(client->datagrams());
  EXPECT_EQ(client->describe(), "udp:127.0.0.1:" + std::to_string(port));

  const std::array<std::uint8_t, 3> hello{1, 2, 3};
  EXPECT_FALSE(server->send(hello)) << "no peer before the first datagram";
  EXPECT_THAT(server->error(), HasSubstr("no peer"));
  std::array<std::uint8_t, 16> empty{};
  EXPECT_EQ(server->receive(empty), 0u) << "non-blocking: nothing pending";

  ASSERT_TRUE(client->send(hello));
  EXPECT_EQ(receive_within(*server, 1'000'000'000),
            std::vector<std::uint8_t>(hello.begin(), hello.end()));
  const std::array<std::uint8_t, 2> reply{9, 8};
  ASSERT_TRUE(server->send(reply));
  EXPECT_EQ(receive_within(*client, 1'000'000'000),
            std::vector<std::uint8_t>(reply.begin(), reply.end()));
  EXPECT_FALSE(client->wait_readable(1'000'000)) << "nothing more pending";
}

TEST(Transport, UdpCarriesParsedFramesOneDatagramEach) {
  const int port = test_port(1);
  auto server = open_transport("udp-listen:127.0.0.1:" + std::to_string(port));
  auto client = open_transport("udp:localhost:" + std::to_string(port));
  Encoder encoder(1, 191);
  std::array<std::uint8_t, kMaxFrameSize> frame{};
  const std::size_t n = encoder.encode(Heartbeat{}, frame);
  ASSERT_TRUE(client->send(std::span<const std::uint8_t>(frame.data(), n)));
  const auto got = receive_within(*server, 1'000'000'000);
  Parser parser;
  int frames = 0;
  parser.feed(got, [&](const FrameHeader& h, const Message&) {
    ++frames;
    EXPECT_EQ(h.component_id, 191);
  });
  EXPECT_EQ(frames, 1);
}

TEST(Transport, SerialThroughAPseudoTerminal) {
  int master = -1;
  int slave = -1;
  std::array<char, 128> name{};
  ASSERT_EQ(::openpty(&master, &slave, name.data(), nullptr, nullptr), 0);
  auto port = open_transport(std::string("serial:") + name.data() + ":921600");
  ::close(slave);
  termios raw{};
  ASSERT_EQ(::tcgetattr(master, &raw), 0);
  ::cfmakeraw(&raw);
  ::tcsetattr(master, TCSANOW, &raw);
  EXPECT_FALSE(port->datagrams());

  Encoder encoder(1, 1);
  std::array<std::uint8_t, kMaxFrameSize> frame{};
  const Attitude att{42, 0.1f, 0.2f, 0.3f, 0, 0, 0};
  const std::size_t n = encoder.encode(att, frame);
  ASSERT_EQ(::write(master, frame.data(), n), static_cast<ssize_t>(n));

  Parser parser;
  std::vector<Message> got;
  std::array<std::uint8_t, 512> buffer{};
  for (int i = 0; i < 20 && got.empty(); ++i) {
    if (!port->wait_readable(100'000'000)) continue;
    const std::size_t k = port->receive(buffer);
    parser.feed(std::span<const std::uint8_t>(buffer.data(), k),
                [&](const FrameHeader&, const Message& m) { got.push_back(m); });
  }
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], Message(att));

  // Bytes containing 0x0A, 0x0D, 0x11, 0x13 must pass untouched (raw mode: no CR/LF mapping, no
  // XON/XOFF).
  const std::array<std::uint8_t, 6> binary{0x0A, 0x0D, 0x11, 0x13, 0x03, 0xFD};
  ASSERT_TRUE(port->send(binary));
  std::array<std::uint8_t, 16> back{};
  std::size_t have = 0;
  for (int i = 0; i < 20 && have < binary.size(); ++i) {
    const ssize_t r = ::read(master, back.data() + have, back.size() - have);
    if (r > 0)
      have += static_cast<std::size_t>(r);
    else
      ::usleep(10'000);
  }
  ASSERT_EQ(have, binary.size());
  EXPECT_TRUE(std::equal(binary.begin(), binary.end(), back.begin()));
  ::close(master);
}

TEST(Transport, BadSpecsNameTheSpecAndTheProblem) {
  using hq::testing::input_error_message;
  EXPECT_EQ(input_error_message([] { open_transport("udp:127.0.0.1:99999"); }),
            "mavlink transport \"udp:127.0.0.1:99999\": port 99999 out of range 1..65535");
  EXPECT_THAT(input_error_message([] { open_transport("udp:127.0.0.1:abc"); }),
              HasSubstr("port \"abc\" is not a number"));
  EXPECT_THAT(input_error_message([] { open_transport("udp:14540"); }),
              HasSubstr("expected udp:HOST:PORT"));
  EXPECT_THAT(input_error_message([] { open_transport("tcp:127.0.0.1:5760"); }),
              HasSubstr("unknown kind \"tcp\""));
  EXPECT_THAT(input_error_message([] { open_transport("udp14540"); }),
              HasSubstr("expected udp:HOST:PORT, udp-listen:[HOST:]PORT or serial:DEVICE:BAUD"));
  EXPECT_THAT(input_error_message([] { open_transport("udp-listen:0"); }),
              HasSubstr("port 0 out of range 1..65535"));
  EXPECT_THAT(input_error_message([] { open_transport("udp:no.such.host.invalid:14540"); }),
              HasSubstr("cannot resolve host \"no.such.host.invalid\""));
  EXPECT_EQ(
      input_error_message([] { open_transport("serial:/dev/ttyACM0:12345"); })
          .rfind(
              "mavlink transport \"serial:/dev/ttyACM0:12345\": baud rate 12345 is not a termios "
              "rate",
              0),
      0u);
  EXPECT_THAT(input_error_message([] { open_transport("serial:/nonexistent/tty:115200"); }),
              HasSubstr("cannot open /nonexistent/tty: No such file or directory"));
  EXPECT_THAT(input_error_message([] { open_transport("serial:/dev/null:115200"); }),
              HasSubstr("/dev/null is not a serial port"));
}

// A supervisor starts hq-onboard again for a port that is not there yet (a USB flight controller
// still booting), never for one that is wrong.
TEST(Transport, AnAbsentSerialPortIsADeviceThatMayYetAppearAWrongOneIsNot) {
  EXPECT_THROW(open_transport("serial:/nonexistent/tty:115200"), DeviceUnavailableError);
  try {
    open_transport("serial:/dev/null:115200");
    ADD_FAILURE() << "/dev/null opened as a serial port";
  } catch (const DeviceUnavailableError& e) {
    ADD_FAILURE() << "not a serial port, yet called a device that may appear: " << e.what();
  } catch (const InputError&) {
  }
}

}  // namespace
}  // namespace hq::mavlink
