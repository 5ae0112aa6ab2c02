#include "hq/base/error.hpp"

#include "backends.hpp"

#include <dhdc.h>
#include <string>

namespace hq::haptics {
namespace {

/// Force Dimension device (omega.x, delta.x, ...) through the dhd C API. The SDK's frame has x
/// out of the base towards the operator, y right, z up; D (NED, x away from the operator, z
/// down) is that frame turned by pi about y: D = (-x, y, -z), forces likewise.
class ForceDimensionDevice final : public HapticDevice {
 public:
  ForceDimensionDevice() {
    id_ = dhdOpen();
    if (id_ < 0) throw InputError(std::string("forcedim: dhdOpen: ") + dhdErrorGetLastStr());
    dhdEnableForce(DHD_ON, static_cast<char>(id_));
    double x = 0.0;
    double y = 0.0;
    double z = 0.0;
    if (dhdGetPosition(&x, &y, &z, static_cast<char>(id_)) < 0) {
      const std::string error = dhdErrorGetLastStr();
      dhdClose(static_cast<char>(id_));
      throw InputError("forcedim: dhdGetPosition: " + error);
    }
    // D's origin is the resting point of the end effector (core paper §3.3): where it is now.
    rest_sdk_m_ = Eigen::Vector3d(x, y, z);
    set_status("forcedim: {} connected", dhdGetSystemName(static_cast<char>(id_)));
  }
  ~ForceDimensionDevice() override {
    dhdSetForce(0.0, 0.0, 0.0, static_cast<char>(id_));
    dhdClose(static_cast<char>(id_));
  }

  bool read(std::int64_t /*t_ns*/, DeviceSample& out) override {
    out = DeviceSample{};
    if (!connected_) return false;
    double x = 0.0;
    double y = 0.0;
    double z = 0.0;
    if (dhdGetPosition(&x, &y, &z, static_cast<char>(id_)) < 0) {
      connected_ = false;
      set_status("forcedim: device lost ({}): command zero", dhdErrorGetLastStr());
      return false;
    }
    const Eigen::Vector3d d_sdk_m = Eigen::Vector3d(x, y, z) - rest_sdk_m_;
    out.p_D_m = Eigen::Vector3d(-d_sdk_m.x(), d_sdk_m.y(), -d_sdk_m.z());
    out.buttons = static_cast<std::uint32_t>(dhdGetButtonMask(static_cast<char>(id_)));
    return true;
  }

  void write_force(std::int64_t /*t_ns*/, const Eigen::Vector3d& F_D_n) override {
    if (!connected_) return;
    const Eigen::Vector3d F = F_D_n.allFinite() ? F_D_n : Eigen::Vector3d::Zero();
    if (dhdSetForce(-F.x(), F.y(), -F.z(), static_cast<char>(id_)) < 0) {
      connected_ = false;
      set_status("forcedim: dhdSetForce failed ({}): command zero", dhdErrorGetLastStr());
    }
  }

  [[nodiscard]] const char* name() const override { return "forcedim"; }
  [[nodiscard]] bool connected() const override { return connected_; }

 private:
  int id_ = -1;
  bool connected_ = true;
  Eigen::Vector3d rest_sdk_m_ = Eigen::Vector3d::Zero();
};

}  // namespace

std::unique_ptr<HapticDevice> open_force_dimension() {
  return std::make_unique<ForceDimensionDevice>();
}

}  // namespace hq::haptics
