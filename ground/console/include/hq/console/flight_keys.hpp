#pragma once
/// Keys held in the console window for keyboard flying, shared between the UI thread (which
/// sees SDL's key events and writes) and the haptic thread (whose keyboard device reads). One
/// atomic word each way: neither side locks, allocates or waits for the other.
///
/// The keys are intents, not device axes: the window's keyboard device turns them into an end
/// effector displacement in D that TeleopMapping (eq. 6-10) maps to the intended command.

#include <atomic>
#include <cstdint>

namespace hq::console {

/// Bits of FlightKeys::held().
enum FlightKey : std::uint32_t {
  kKeyForward = 1u << 0,   ///< W, up arrow.
  kKeyBack = 1u << 1,      ///< S, down arrow.
  kKeyYawLeft = 1u << 2,   ///< Q, A, left arrow (the mapping has no lateral axis, eq. 10).
  kKeyYawRight = 1u << 3,  ///< E, D, right arrow.
  kKeyClimb = 1u << 4,     ///< Page up.
  kKeyDescend = 1u << 5,   ///< Page down.
};

class FlightKeys {
 public:
  /// UI thread: a key went down or up (bits of FlightKey).
  void press(std::uint32_t key) { held_.fetch_or(key, std::memory_order_relaxed); }
  void release(std::uint32_t key) { held_.fetch_and(~key, std::memory_order_relaxed); }
  /// UI thread: focus lost or window closing; nothing stays held.
  void release_all() { held_.store(0, std::memory_order_relaxed); }
  /// UI thread: the window is up (true) or gone (false); a gone window reads as device loss.
  void set_window_open(bool open) {
    if (!open) release_all();
    window_open_.store(open, std::memory_order_release);
  }

  /// Haptic thread.
  [[nodiscard]] std::uint32_t held() const { return held_.load(std::memory_order_relaxed); }
  [[nodiscard]] bool window_open() const { return window_open_.load(std::memory_order_acquire); }

 private:
  std::atomic<std::uint32_t> held_{0};
  std::atomic<bool> window_open_{false};
};

}  // namespace hq::console
