#pragma once
// Pieces shared by the camera adapters: intrinsics, device clocks, the reconnect loop.

#include "hq/config/camera_info.hpp"
#include "hq/sources/camera_sources.hpp"

#include <chrono>
#include <cstdint>
#include <string>
#include <utility>

namespace hq::sources::detail {

/// The camera file options.camera_file, else default_file; throws hq::InputError if it cannot be
/// read or its size differs from the stream mode.
config::CameraInfo load_camera_for(const CameraSourceOptions& options,
                                   const std::string& default_file, const std::string& who);

/// Checks the options' ranges; throws hq::InputError naming who and the field.
void check_options(const CameraSourceOptions& options, const std::string& who);

/// Turns a device tick counter into t_ns: the host's system clock at the first tick plus the
/// elapsed device time, so stamps keep the device's spacing but look like TUM's Unix stamps.
/// Ticks are unwrapped modulo 2^wrap_bits with signed differences, so depth and colour stamps
/// may interleave slightly out of order (libfreenect's 60 MHz uint32 wraps every 71.6 s).
class DeviceClock {
 public:
  /// ns = ticks * ns_num / ns_den (60 MHz: 50/3; microseconds: 1000/1).
  DeviceClock(std::int64_t ns_num, std::int64_t ns_den, int wrap_bits)
      : ns_num_(ns_num), ns_den_(ns_den), wrap_bits_(wrap_bits) {}
  std::int64_t to_ns(std::uint64_t ticks);
  /// Forgets the anchor (a reopened device restarts its counter).
  void reset() { started_ = false; }

 private:
  std::int64_t ns_num_, ns_den_;
  int wrap_bits_;
  bool started_ = false;
  std::uint64_t last_ticks_ = 0;
  std::int64_t unwrapped_ticks_ = 0;
  std::int64_t anchor_ns_ = 0;
};

/// The reconnect loop of a camera adapter: after a loss the device is reopened at most once per
/// retry interval, and error() says why there is no frame. Used as
///   if (!open_ && !reconnect_.reopen([&](std::string& why) { return open_device(why); },
///                                    error_)) return FrameStatus::kNoFrame;
///   ... on a read failure: close the device, error_ = reconnect_.lost(why).
class Reconnector {
 public:
  Reconnector(std::string name, std::int64_t retry_interval_ns)
      : name_(std::move(name)), interval_(retry_interval_ns) {}

  /// Tries open_device(std::string& why) if an attempt is due. True once it opened; otherwise
  /// error holds why (the attempt's reason and "; retrying", or is left as the loss said).
  template <typename OpenDevice>
  bool reopen(OpenDevice&& open_device, std::string& error) {
    const auto now = std::chrono::steady_clock::now();
    if (now < next_) return false;
    next_ = now + interval_;
    std::string why;
    if (open_device(why)) return true;
    error = why + "; retrying";
    return false;
  }

  /// error() after the device was lost for `why`.
  [[nodiscard]] std::string lost(const std::string& why) const {
    return name_ + ": device lost (" + why + "); retrying every " +
           std::to_string(interval_.count() / 1'000'000) + " ms";
  }

 private:
  std::string name_;
  std::chrono::nanoseconds interval_;
  std::chrono::steady_clock::time_point next_{};
};

}  // namespace hq::sources::detail
