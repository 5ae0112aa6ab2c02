#include "hq/base/error.hpp"
#include "hq/haptics/haptic_device.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <string>
#include <termios.h>
#include <unistd.h>

namespace hq::haptics {
namespace {

constexpr char kEscape = 27;

/// stdin (or another fd) in raw, non-blocking mode; the previous mode comes back on destruction,
/// so a crash-free exit always leaves a usable terminal.
class TerminalSource final : public ByteSource {
 public:
  explicit TerminalSource(int fd) : fd_(fd) {
    if (!isatty(fd)) {
      throw InputError("keyboard device: fd " + std::to_string(fd) +
                       " is not a terminal; run hq-ground in a terminal or use --device sim");
    }
    if (tcgetattr(fd, &saved_) != 0) {
      throw InputError(std::string("keyboard device: tcgetattr: ") + std::strerror(errno));
    }
    termios raw = saved_;
    // No line buffering or echo; keep ISIG so Ctrl-C still stops the program.
    raw.c_lflag &= static_cast<tcflag_t>(~(ICANON | ECHO));
    raw.c_cc[VMIN] = 0;
    raw.c_cc[VTIME] = 0;
    if (tcsetattr(fd, TCSANOW, &raw) != 0) {
      throw InputError(std::string("keyboard device: tcsetattr: ") + std::strerror(errno));
    }
    saved_flags_ = fcntl(fd, F_GETFL);
    if (saved_flags_ >= 0) fcntl(fd, F_SETFL, saved_flags_ | O_NONBLOCK);
  }
  ~TerminalSource() override {
    if (saved_flags_ >= 0) fcntl(fd_, F_SETFL, saved_flags_);
    tcsetattr(fd_, TCSANOW, &saved_);
  }
  TerminalSource(const TerminalSource&) = delete;
  TerminalSource& operator=(const TerminalSource&) = delete;

  int read_available(char* buffer, int capacity) override {
    const ssize_t n = ::read(fd_, buffer, static_cast<std::size_t>(capacity));
    if (n > 0) return static_cast<int>(n);
    if (n == 0) return -1;  // end of file: the terminal went away
    return (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) ? 0 : -1;
  }

 private:
  int fd_;
  termios saved_{};
  int saved_flags_ = -1;
};

}  // namespace

std::unique_ptr<ByteSource> open_terminal(int fd) { return std::make_unique<TerminalSource>(fd); }

KeyboardDevice::KeyboardDevice(const KeyboardConfig& config, std::unique_ptr<ByteSource> input)
    : config_(config), input_(std::move(input)) {
  if (!input_) throw InputError("keyboard device: no input source");
  set_status("keyboard: w/s fwd/back, a/d left/right, r/f up/down, space centre, 1-8 buttons");
}

void KeyboardDevice::apply_key(char key) {
  // Arrow keys arrive as ESC [ A..D.
  if (escape_state_ == 1) {
    escape_state_ = key == '[' ? 2 : 0;
    return;
  }
  if (escape_state_ == 2) {
    escape_state_ = 0;
    switch (key) {
      case 'A':
        key = 'w';
        break;
      case 'B':
        key = 's';
        break;
      case 'C':
        key = 'd';
        break;
      case 'D':
        key = 'a';
        break;
      default:
        return;
    }
  }
  const double step = config_.step_m;
  switch (key) {
    case kEscape:
      escape_state_ = 1;
      return;
    case 'w':
      p_D_m_.x() += step;
      break;
    case 's':
      p_D_m_.x() -= step;
      break;
    case 'd':
      p_D_m_.y() += step;
      break;
    case 'a':
      p_D_m_.y() -= step;
      break;
    case 'f':
      p_D_m_.z() += step;
      break;
    case 'r':
      p_D_m_.z() -= step;
      break;
    case ' ':
      p_D_m_.setZero();
      break;
    default:
      if (key >= '1' && key <= '8') pending_buttons_ |= 1u << (key - '1');
      return;
  }
  p_D_m_ = p_D_m_.cwiseMax(-config_.range_m).cwiseMin(config_.range_m);
}

bool KeyboardDevice::read(std::int64_t /*t_ns*/, DeviceSample& out) {
  out = DeviceSample{};
  if (!connected_) return false;
  char buffer[64];
  for (;;) {
    const int n = input_->read_available(buffer, static_cast<int>(sizeof(buffer)));
    if (n < 0) {
      connected_ = false;
      p_D_m_.setZero();
      set_status("keyboard: input closed: command zero");
      return false;
    }
    for (int i = 0; i < n; ++i) apply_key(buffer[i]);
    if (n < static_cast<int>(sizeof(buffer))) break;
  }
  out.p_D_m = p_D_m_;
  out.buttons = pending_buttons_;
  pending_buttons_ = 0;
  return true;
}

void KeyboardDevice::write_force(std::int64_t /*t_ns*/, const Eigen::Vector3d& /*F_D_n*/) {}

}  // namespace hq::haptics
