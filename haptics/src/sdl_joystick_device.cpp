#include "hq/base/error.hpp"

#include "backends.hpp"

#include <SDL.h>
#include <algorithm>
#include <cmath>
#include <string>

namespace hq::haptics {
namespace {

constexpr double kAxisFullScale = 32767.0;
// Rumble is re-sent only on a visible change or before the last one runs out: SDL's haptic
// calls go to the kernel, too slow to repeat 1000 times a second.
constexpr double kRumbleStepFraction = 0.05;
constexpr std::int64_t kRumbleRefreshNs = 100'000'000;
constexpr Uint32 kRumbleLengthMs = 250;

class SdlJoystickDevice final : public HapticDevice {
 public:
  explicit SdlJoystickDevice(const JoystickConfig& config) : config_(config) {
    SDL_SetHint(SDL_HINT_JOYSTICK_ALLOW_BACKGROUND_EVENTS, "1");
    if (SDL_Init(SDL_INIT_JOYSTICK | SDL_INIT_GAMECONTROLLER | SDL_INIT_HAPTIC | SDL_INIT_EVENTS) !=
        0) {
      throw InputError(std::string("joystick device: SDL_Init: ") + SDL_GetError());
    }
    const int count = SDL_NumJoysticks();
    if (count <= config.index) {
      SDL_Quit();
      throw InputError("joystick device: index " + std::to_string(config.index) + " requested, " +
                       std::to_string(std::max(count, 0)) +
                       " joystick(s) or gamepad(s) found by SDL");
    }
    if (!open(config.index)) {
      const std::string error = SDL_GetError();
      SDL_Quit();
      throw InputError("joystick device: cannot open index " + std::to_string(config.index) + ": " +
                       error);
    }
  }
  ~SdlJoystickDevice() override {
    close();
    SDL_Quit();
  }

  bool read(std::int64_t /*t_ns*/, DeviceSample& out) override {
    out = DeviceSample{};
    SDL_Event event;
    while (SDL_PollEvent(&event) != 0) handle(event);
    if (joystick_ == nullptr) return false;
    const double range = config_.range_m;
    if (controller_ != nullptr) {
      const auto axis = [&](SDL_GameControllerAxis a) {
        return SDL_GameControllerGetAxis(controller_, a) / kAxisFullScale;
      };
      // Left stick up (negative SDL y) pushes the handle forward; right stick moves it sideways
      // (x) and down (y), as a 3-DOF handle would.
      out.p_D_m =
          Eigen::Vector3d(-axis(SDL_CONTROLLER_AXIS_LEFTY), axis(SDL_CONTROLLER_AXIS_RIGHTX),
                          axis(SDL_CONTROLLER_AXIS_RIGHTY)) *
          range;
      for (int b = 0; b < SDL_CONTROLLER_BUTTON_MAX && b < 32; ++b) {
        if (SDL_GameControllerGetButton(controller_, static_cast<SDL_GameControllerButton>(b))) {
          out.buttons |= 1u << b;
        }
      }
    } else {
      const int axes = SDL_JoystickNumAxes(joystick_);
      const auto axis = [&](int a) {
        return a < axes ? SDL_JoystickGetAxis(joystick_, a) / kAxisFullScale : 0.0;
      };
      out.p_D_m = Eigen::Vector3d(-axis(1), axis(0), axis(3)) * range;
      const int buttons = std::min(SDL_JoystickNumButtons(joystick_), 32);
      for (int b = 0; b < buttons; ++b) {
        if (SDL_JoystickGetButton(joystick_, b) != 0) out.buttons |= 1u << b;
      }
    }
    out.p_D_m = out.p_D_m.cwiseMax(-range).cwiseMin(range);
    return true;
  }

  void write_force(std::int64_t t_ns, const Eigen::Vector3d& F_D_n) override {
    if (haptic_ == nullptr) return;
    const double magnitude = F_D_n.allFinite() ? F_D_n.norm() : 0.0;
    const double strength = std::clamp(magnitude / config_.rumble_full_scale_n, 0.0, 1.0);
    const bool changed = std::abs(strength - last_strength_) > kRumbleStepFraction;
    if (!changed && t_ns - last_rumble_ns_ < kRumbleRefreshNs) return;
    if (strength < kRumbleStepFraction) {
      SDL_HapticRumbleStop(haptic_);
    } else {
      SDL_HapticRumblePlay(haptic_, static_cast<float>(strength), kRumbleLengthMs);
    }
    last_strength_ = strength;
    last_rumble_ns_ = t_ns;
  }

  [[nodiscard]] const char* name() const override { return "joystick"; }
  [[nodiscard]] bool connected() const override { return joystick_ != nullptr; }

 private:
  bool open(int index) {
    if (SDL_IsGameController(index)) {
      controller_ = SDL_GameControllerOpen(index);
      if (controller_ == nullptr) return false;
      joystick_ = SDL_GameControllerGetJoystick(controller_);
    } else {
      joystick_ = SDL_JoystickOpen(index);
      if (joystick_ == nullptr) return false;
    }
    instance_id_ = SDL_JoystickInstanceID(joystick_);
    haptic_ = SDL_HapticOpenFromJoystick(joystick_);
    if (haptic_ != nullptr &&
        (SDL_HapticRumbleSupported(haptic_) != SDL_TRUE || SDL_HapticRumbleInit(haptic_) != 0)) {
      SDL_HapticClose(haptic_);
      haptic_ = nullptr;
    }
    set_status("joystick '{}' connected, {}", SDL_JoystickName(joystick_),
               haptic_ != nullptr ? "rumble as force cue" : "no force feedback");
    return true;
  }

  void close() {
    if (haptic_ != nullptr) SDL_HapticClose(haptic_);
    if (controller_ != nullptr) {
      SDL_GameControllerClose(controller_);
    } else if (joystick_ != nullptr) {
      SDL_JoystickClose(joystick_);
    }
    haptic_ = nullptr;
    controller_ = nullptr;
    joystick_ = nullptr;
    last_strength_ = 0.0;
  }

  void handle(const SDL_Event& event) {
    const bool added =
        event.type == SDL_CONTROLLERDEVICEADDED ||
        (event.type == SDL_JOYDEVICEADDED && !SDL_IsGameController(event.jdevice.which));
    const bool removed =
        event.type == SDL_CONTROLLERDEVICEREMOVED || event.type == SDL_JOYDEVICEREMOVED;
    if (added && joystick_ == nullptr) {
      // For ADDED events `which` is a device index; for REMOVED an instance id.
      if (!open(event.cdevice.which))
        set_status("joystick: plugged in but not opened: {}", SDL_GetError());
    } else if (removed && joystick_ != nullptr && event.cdevice.which == instance_id_) {
      close();
      set_status("joystick removed: command zero; plug a joystick or gamepad back in");
    }
  }

  JoystickConfig config_;
  SDL_GameController* controller_ = nullptr;
  SDL_Joystick* joystick_ = nullptr;
  SDL_Haptic* haptic_ = nullptr;
  SDL_JoystickID instance_id_ = -1;
  double last_strength_ = 0.0;
  std::int64_t last_rumble_ns_ = 0;
};

}  // namespace

std::unique_ptr<HapticDevice> open_sdl_joystick(const JoystickConfig& config) {
  return std::make_unique<SdlJoystickDevice>(config);
}

}  // namespace hq::haptics
