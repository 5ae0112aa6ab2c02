#pragma once
// Backends that exist only when their library was found; open_device() is their one caller.

#include "hq/haptics/haptic_device.hpp"

#include <memory>

namespace hq::haptics {

#ifdef HQ_HAVE_SDL2
/// SDL2 gamepad (or plain joystick) as a virtual end effector; rumble as a force-magnitude cue.
std::unique_ptr<HapticDevice> open_sdl_joystick(const JoystickConfig& config);
#endif

#ifdef HQ_HAVE_FORCE_DIMENSION
/// Force Dimension device through the dhd C API; D origin at the handle's position when opened.
std::unique_ptr<HapticDevice> open_force_dimension();
#endif

}  // namespace hq::haptics
