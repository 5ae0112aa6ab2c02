#include "alarm.hpp"

#include "hq/base/log.hpp"

#include <SDL.h>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>

namespace hq::console {

AlarmCause alarm_cause(const Snapshot& s) {
  if (s.replay.active || !s.have_state) return AlarmCause::kNone;
  if (s.link.link_lost) return AlarmCause::kLinkLost;
  // The vehicle's own word that it is in a fail-safe (holding or landing on its own).
  if (std::strcmp(s.operator_input, "commands ignored: fail-safe") == 0) {
    return AlarmCause::kFailsafe;
  }
  return AlarmCause::kNone;
}

const char* to_string(AlarmCause cause) {
  switch (cause) {
    case AlarmCause::kLinkLost:
      return "link lost";
    case AlarmCause::kFailsafe:
      return "fail-safe";
    default:
      return "none";
  }
}

bool AlarmMute::update(AlarmCause cause, bool toggle_requested) {
  if (cause == AlarmCause::kNone || cause != muted_cause_) muted_ = false;
  if (toggle_requested && cause != AlarmCause::kNone) muted_ = !muted_;
  muted_cause_ = muted_ ? cause : AlarmCause::kNone;
  return muted_;
}

AlarmTone::AlarmTone() {
  if (SDL_InitSubSystem(SDL_INIT_AUDIO) != 0) {
    status_ = std::string("no audio (") + SDL_GetError() + ")";
  } else {
    SDL_AudioSpec want{};
    want.freq = rate_hz_;
    want.format = AUDIO_F32SYS;
    want.channels = 1;
    want.samples = 1024;
    want.callback = &AlarmTone::callback;
    want.userdata = this;
    SDL_AudioSpec have{};
    device_ = SDL_OpenAudioDevice(nullptr, 0, &want, &have, 0);
    if (device_ == 0) {
      status_ = std::string("no audio device (") + SDL_GetError() + ")";
      SDL_QuitSubSystem(SDL_INIT_AUDIO);
    } else {
      rate_hz_ = have.freq;
      const char* driver = SDL_GetCurrentAudioDriver();
      status_ = driver != nullptr ? driver : "audio";
      SDL_PauseAudioDevice(device_, 0);
    }
  }
  if (device_ == 0) {
    hq::log::warn("hq-ground: {}: alarms are shown, not heard\n", status_);
  }
}

AlarmTone::~AlarmTone() {
  if (device_ != 0) {
    SDL_CloseAudioDevice(device_);
    SDL_QuitSubSystem(SDL_INIT_AUDIO);
  }
}

void AlarmTone::callback(void* self, std::uint8_t* stream, int bytes) {
  static_cast<AlarmTone*>(self)->fill(reinterpret_cast<float*>(stream),
                                      bytes / static_cast<int>(sizeof(float)));
}

// Link lost: a two-tone siren (880 / 660 Hz, 4 changes a second), unmistakable for anything
// else on a desk. Fail-safe: a 440 Hz beep, 0.2 s on, 0.3 s off.
void AlarmTone::fill(float* out, int samples) {
  const auto cause = static_cast<AlarmCause>(cause_.load(std::memory_order_relaxed));
  const double rate = rate_hz_;
  std::uint64_t tone = 0;
  for (int i = 0; i < samples; ++i, ++t_samples_) {
    const double t_s = static_cast<double>(t_samples_) / rate;
    double frequency_hz = 0;
    if (cause == AlarmCause::kLinkLost) {
      frequency_hz = std::fmod(t_s, 0.5) < 0.25 ? 880.0 : 660.0;
    } else if (cause == AlarmCause::kFailsafe && std::fmod(t_s, 0.5) < 0.2) {
      frequency_hz = 440.0;
    }
    if (frequency_hz > 0) {
      phase_ += 2.0 * std::numbers::pi * frequency_hz / rate;
      if (phase_ > 2.0 * std::numbers::pi) phase_ -= 2.0 * std::numbers::pi;
      out[i] = static_cast<float>(0.25 * std::sin(phase_));
      ++tone;
    } else {
      out[i] = 0.0F;
    }
  }
  tone_samples_.fetch_add(tone, std::memory_order_relaxed);
}

}  // namespace hq::console
