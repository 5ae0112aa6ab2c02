#include "hq/mavlink/transport.hpp"

#include "hq/base/error.hpp"

#include <algorithm>
#include <arpa/inet.h>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

namespace hq::mavlink {
namespace {

[[noreturn]] void fail(const std::string& spec, const std::string& what) {
  throw InputError("mavlink transport \"" + spec + "\": " + what);
}

std::string errno_text(int error) { return std::strerror(error); }

// The error text lives in a string reserved once, so a failing send on the hot path does not
// allocate to say why.
void set_error(std::string& out, const char* what, int error) {
  out.clear();
  out.append(what);
  out.append(": ");
  const char* text = strerrordesc_np(error);
  out.append(text != nullptr ? text : "unknown error");
}

int parse_int(const std::string& spec, const std::string& text, const char* name, long min,
              long max) {
  long value = 0;
  const auto* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value);
  if (text.empty() || ec != std::errc() || ptr != end) {
    fail(spec, std::string(name) + " \"" + text + "\" is not a number");
  }
  if (value < min || value > max) {
    fail(spec, std::string(name) + " " + text + " out of range " + std::to_string(min) + ".." +
                   std::to_string(max));
  }
  return static_cast<int>(value);
}

sockaddr_in resolve(const std::string& spec, const std::string& host, int port) {
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  if (inet_pton(AF_INET, host.c_str(), &addr.sin_addr) == 1) return addr;
  addrinfo hints{};
  hints.ai_family = AF_INET;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* result = nullptr;
  const int rc = getaddrinfo(host.c_str(), nullptr, &hints, &result);
  if (rc != 0 || result == nullptr) {
    fail(spec, "cannot resolve host \"" + host + "\": " + gai_strerror(rc));
  }
  addr.sin_addr = reinterpret_cast<const sockaddr_in*>(result->ai_addr)->sin_addr;
  freeaddrinfo(result);
  return addr;
}

bool poll_fd(int fd, std::int64_t timeout_ns) {
  pollfd p{fd, POLLIN, 0};
  const std::int64_t ms = timeout_ns <= 0 ? 0 : (timeout_ns + 999'999) / 1'000'000;
  const int rc = ::poll(&p, 1, static_cast<int>(std::min<std::int64_t>(ms, 1'000'000)));
  return rc > 0 && (p.revents & POLLIN) != 0;
}

class FdTransport : public Transport {
 public:
  explicit FdTransport(std::string spec) : spec_(std::move(spec)) { error_.reserve(160); }
  ~FdTransport() override {
    if (fd_ >= 0) ::close(fd_);
  }
  FdTransport(const FdTransport&) = delete;
  FdTransport& operator=(const FdTransport&) = delete;
  bool wait_readable(std::int64_t timeout_ns) override { return poll_fd(fd_, timeout_ns); }
  [[nodiscard]] const std::string& describe() const override { return spec_; }
  [[nodiscard]] const std::string& error() const override { return error_; }

 protected:
  std::string spec_;
  std::string error_;
  int fd_ = -1;
};

class UdpTransport final : public FdTransport {
 public:
  // listen: bind `addr` and answer the latest sender; otherwise send to `addr` from an
  // ephemeral port and receive on it.
  UdpTransport(const std::string& spec, const sockaddr_in& addr, bool listen)
      : FdTransport(spec), listen_(listen) {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd_ < 0) fail(spec, "socket(): " + errno_text(errno));
    sockaddr_in local{};
    local.sin_family = AF_INET;
    if (listen) {
      local = addr;
      const int one = 1;
      ::setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof(one));
    } else {
      peer_ = addr;
      has_peer_ = true;
    }
    if (::bind(fd_, reinterpret_cast<const sockaddr*>(&local), sizeof(local)) != 0) {
      fail(spec, "bind(): " + errno_text(errno));
    }
  }

  bool send(std::span<const std::uint8_t> bytes) override {
    if (!has_peer_) {
      error_.assign("no peer yet: nothing received on the listening port");
      return false;
    }
    const ssize_t n = ::sendto(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL,
                               reinterpret_cast<const sockaddr*>(&peer_), sizeof(peer_));
    if (n != static_cast<ssize_t>(bytes.size())) {
      set_error(error_, "sendto()", n < 0 ? errno : EMSGSIZE);
      return false;
    }
    return true;
  }

  std::size_t receive(std::span<std::uint8_t> buffer) override {
    for (;;) {
      sockaddr_in from{};
      socklen_t from_len = sizeof(from);
      const ssize_t n = ::recvfrom(fd_, buffer.data(), buffer.size(), 0,
                                   reinterpret_cast<sockaddr*>(&from), &from_len);
      if (n < 0) {
        // ECONNREFUSED: an ICMP "port unreachable" for an earlier send (no SITL yet); not data.
        if (errno == EINTR || errno == ECONNREFUSED) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK) set_error(error_, "recvfrom()", errno);
        return 0;
      }
      if (listen_) {
        peer_ = from;
        has_peer_ = true;
      }
      return static_cast<std::size_t>(n);
    }
  }

  [[nodiscard]] bool datagrams() const override { return true; }
  [[nodiscard]] bool has_peer() const override { return has_peer_; }
  [[nodiscard]] std::string peer() const override {
    if (!has_peer_) return {};
    char host[INET_ADDRSTRLEN] = "";
    ::inet_ntop(AF_INET, &peer_.sin_addr, host, sizeof(host));
    return std::string(host) + ":" + std::to_string(ntohs(peer_.sin_port));
  }

 private:
  bool listen_;
  bool has_peer_ = false;
  sockaddr_in peer_{};
};

speed_t baud_constant(const std::string& spec, int baud) {
  switch (baud) {
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 500000:
      return B500000;
    case 576000:
      return B576000;
    case 921600:
      return B921600;
    case 1000000:
      return B1000000;
    case 1500000:
      return B1500000;
    case 2000000:
      return B2000000;
    case 3000000:
      return B3000000;
    default:
      fail(spec, "baud rate " + std::to_string(baud) +
                     " is not a termios rate (9600, 19200, 38400, 57600, 115200, 230400, 460800, "
                     "500000, 576000, 921600, 1000000, 1500000, 2000000, 3000000)");
  }
}

class SerialTransport final : public FdTransport {
 public:
  SerialTransport(const std::string& spec, const std::string& device, int baud)
      : FdTransport(spec) {
    const speed_t speed = baud_constant(spec, baud);
    fd_ = ::open(device.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
    if (fd_ < 0) {
      const int error = errno;
      const std::string what =
          "mavlink transport \"" + spec + "\": cannot open " + device + ": " + errno_text(error);
      // Not there yet (a USB FC still booting) or held by another program: may clear by itself.
      if (error == ENOENT || error == ENODEV || error == ENXIO || error == EBUSY) {
        throw DeviceUnavailableError(what);
      }
      throw InputError(what);
    }
    termios tio{};
    if (::tcgetattr(fd_, &tio) != 0) {
      fail(spec, device + " is not a serial port: " + errno_text(errno));
    }
    ::cfmakeraw(&tio);  // 8 data bits, no parity, no echo, no line editing
    tio.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS | PARENB);
    tio.c_cflag |= CLOCAL | CREAD | CS8;
    tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
    tio.c_cc[VMIN] = 0;
    tio.c_cc[VTIME] = 0;
    if (::cfsetispeed(&tio, speed) != 0 || ::cfsetospeed(&tio, speed) != 0 ||
        ::tcsetattr(fd_, TCSANOW, &tio) != 0) {
      fail(spec, "cannot configure " + device + ": " + errno_text(errno));
    }
    ::tcflush(fd_, TCIOFLUSH);
  }

  bool send(std::span<const std::uint8_t> bytes) override {
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        // A frame half written corrupts the stream for one frame; the FC's parser resyncs.
        set_error(error_, "write()", errno);
        return false;
      }
      done += static_cast<std::size_t>(n);
    }
    return true;
  }

  std::size_t receive(std::span<std::uint8_t> buffer) override {
    for (;;) {
      const ssize_t n = ::read(fd_, buffer.data(), buffer.size());
      if (n < 0) {
        if (errno == EINTR) continue;
        if (errno != EAGAIN && errno != EWOULDBLOCK) set_error(error_, "read()", errno);
        return 0;
      }
      return static_cast<std::size_t>(n);
    }
  }

  [[nodiscard]] bool datagrams() const override { return false; }
};

}  // namespace

std::unique_ptr<Transport> open_transport(const std::string& spec) {
  const auto colon = spec.find(':');
  if (colon == std::string::npos) {
    fail(spec, "expected udp:HOST:PORT, udp-listen:[HOST:]PORT or serial:DEVICE:BAUD");
  }
  const std::string kind = spec.substr(0, colon);
  const std::string rest = spec.substr(colon + 1);
  const auto last = rest.rfind(':');
  if (kind == "udp") {
    if (last == std::string::npos || last == 0) fail(spec, "expected udp:HOST:PORT");
    const int port = parse_int(spec, rest.substr(last + 1), "port", 1, 65535);
    return std::make_unique<UdpTransport>(spec, resolve(spec, rest.substr(0, last), port), false);
  }
  if (kind == "udp-listen") {
    const std::string host = last == std::string::npos ? "127.0.0.1" : rest.substr(0, last);
    const std::string port_text = last == std::string::npos ? rest : rest.substr(last + 1);
    const int port = parse_int(spec, port_text, "port", 1, 65535);
    return std::make_unique<UdpTransport>(spec, resolve(spec, host, port), true);
  }
  if (kind == "serial") {
    if (last == std::string::npos || last == 0) fail(spec, "expected serial:DEVICE:BAUD");
    const int baud = parse_int(spec, rest.substr(last + 1), "baud rate", 1, 100'000'000);
    return std::make_unique<SerialTransport>(spec, rest.substr(0, last), baud);
  }
  fail(spec, "unknown kind \"" + kind + "\", expected udp, udp-listen or serial");
}

}  // namespace hq::mavlink
