#include "hq/base/error.hpp"
#include "hq/haptics/haptic_device.hpp"

#include "backends.hpp"

namespace hq::haptics {

std::unique_ptr<HapticDevice> open_device(const std::string& kind, const DeviceOptions& options) {
  if (kind == "sim") return std::make_unique<SimulatedDevice>(options.config.sim);
  if (kind == "keyboard") {
    return std::make_unique<KeyboardDevice>(options.config.keyboard,
                                            open_terminal(options.terminal_fd));
  }
  if (kind == "joystick") {
#ifdef HQ_HAVE_SDL2
    return open_sdl_joystick(options.config.joystick);
#else
    throw InputError("haptic device 'joystick': not built (CMake did not find SDL2)");
#endif
  }
  if (kind == "forcedim") {
#ifdef HQ_HAVE_FORCE_DIMENSION
    return open_force_dimension();
#else
    throw InputError(
        "haptic device 'forcedim': not built (CMake did not find the Force Dimension SDK: "
        "dhdc.h and libdhd; set CMAKE_PREFIX_PATH to the SDK)");
#endif
  }
  throw InputError("haptic device '" + kind +
                   "': unknown kind, expected sim|keyboard|joystick|forcedim");
}

}  // namespace hq::haptics
