#pragma once
// The console's audible alarm: a tone generated in SDL's audio callback (no sound files), one
// pattern per cause, muted by the operator until the cause clears. Fails soft: without an audio
// device (Xvfb, CI) it says so once and the alarm is shown, not heard.

#include "hq/console/console_model.hpp"

#include <atomic>
#include <cstdint>
#include <string>

namespace hq::console {

enum class AlarmCause : int { kNone = 0, kLinkLost = 1, kFailsafe = 2 };

/// What the console alarms about: the link lost (no vehicle state), else a fail-safe the
/// vehicle reports (it ignores the operator: commands stale or its link lost). Pure.
AlarmCause alarm_cause(const Snapshot& s);
const char* to_string(AlarmCause cause);

/// The operator's mute: holds while the cause it silenced lasts, a new cause sounds again.
class AlarmMute {
 public:
  /// @return whether the alarm is muted for `cause` after this frame.
  bool update(AlarmCause cause, bool toggle_requested);
  [[nodiscard]] bool muted() const { return muted_; }

 private:
  AlarmCause muted_cause_ = AlarmCause::kNone;
  bool muted_ = false;
};

/// The tone on SDL's default audio device (SDL_AUDIODRIVER=dummy or disk in tests).
class AlarmTone {
 public:
  AlarmTone();
  ~AlarmTone();
  AlarmTone(const AlarmTone&) = delete;
  AlarmTone& operator=(const AlarmTone&) = delete;

  /// Sounds `cause` (kNone: silence); lock-free, for every UI frame.
  void play(AlarmCause cause) { cause_.store(static_cast<int>(cause), std::memory_order_relaxed); }
  [[nodiscard]] bool available() const { return device_ != 0; }
  /// "pulseaudio", "dummy", ... or why there is no sound.
  [[nodiscard]] const std::string& status() const { return status_; }
  /// Samples of tone (not silence) handed to the device so far.
  [[nodiscard]] std::uint64_t tone_samples() const {
    return tone_samples_.load(std::memory_order_relaxed);
  }

 private:
  static void callback(void* self, std::uint8_t* stream, int bytes);
  void fill(float* out, int samples);

  std::uint32_t device_ = 0;
  int rate_hz_ = 48000;
  std::string status_;
  std::atomic<int> cause_{0};
  std::atomic<std::uint64_t> tone_samples_{0};
  std::uint64_t t_samples_ = 0;  ///< Audio thread only.
  double phase_ = 0;             ///< Audio thread only.
};

}  // namespace hq::console
