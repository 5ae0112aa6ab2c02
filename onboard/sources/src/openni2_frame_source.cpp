#include "openni2_frame_source.hpp"

#include "hq/base/error.hpp"

#include "camera_common.hpp"
#include <opencv2/imgproc.hpp>

#include <OpenNI.h>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>

namespace hq::sources::detail {

namespace {

constexpr int kWaitStepMs = 100;
constexpr std::int64_t kNsPerUsNum = 1000;  // OpenNI2 frame stamps are device microseconds

std::string mode_text(const openni::VideoMode& mode) {
  return std::to_string(mode.getResolutionX()) + "x" + std::to_string(mode.getResolutionY()) + "@" +
         std::to_string(mode.getFps());
}

bool is_depth_format(openni::PixelFormat format) {
  return format == openni::PIXEL_FORMAT_DEPTH_1_MM || format == openni::PIXEL_FORMAT_DEPTH_100_UM;
}

class Openni2FrameSource final : public CameraSource {
 public:
  Openni2FrameSource(const std::string& uri, const CameraSourceOptions& options)
      : uri_(uri),
        name_("openni2:" + (uri.empty() ? std::string("<any device>") : uri)),
        options_(options),
        is_file_(uri.size() > 4 && uri.compare(uri.size() - 4, 4, ".oni") == 0),
        clock_(kNsPerUsNum, 1, 64),
        reconnect_(name_, options.retry_interval_ns) {
    if (is_file_ && !std::ifstream(uri)) {
      throw InputError(name_ + ": cannot read the .oni file (missing or unreadable)");
    }
    if (openni::OpenNI::initialize() != openni::STATUS_OK) {
      throw InputError(name_ +
                       ": OpenNI::initialize failed: " + openni::OpenNI::getExtendedError());
    }
    initialized_ = true;
    try {
      std::string why;
      if (!open_device(why)) {
        // A recording that does not open stays broken; a camera may be plugged in yet.
        if (is_file_) throw InputError(why);
        throw DeviceUnavailableError(why);
      }
      if (options.camera_file.empty() && has_fov_intrinsics()) {
        camera_ = fov_intrinsics();
      } else {
        camera_ = load_camera_for(options_, "calib/xtion_pro_live.yaml", name_);
        intrinsics_from_ =
            options.camera_file.empty() ? "calib/xtion_pro_live.yaml" : options.camera_file;
      }
    } catch (const InputError&) {
      close_device();
      openni::OpenNI::shutdown();
      throw;
    }
    undistorter_.emplace(camera_);
    bgr_raw_.create(options.height, options.width, CV_8UC3);
    depth_m_raw_.create(options.height, options.width, CV_32FC1);
  }

  ~Openni2FrameSource() override {
    close_device();
    if (initialized_) openni::OpenNI::shutdown();
  }
  Openni2FrameSource(const Openni2FrameSource&) = delete;
  Openni2FrameSource& operator=(const Openni2FrameSource&) = delete;

  FrameStatus next(RgbdFrame& frame) override {
    if (end_of_file_) return FrameStatus::kEndOfStream;
    if (!open_ &&
        !reconnect_.reopen([this](std::string& why) { return open_device(why); }, error_)) {
      return FrameStatus::kNoFrame;
    }
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::nanoseconds(options_.frame_timeout_ns);
    bool have_depth = false, have_colour = false;
    openni::VideoStream* streams[2] = {&depth_, &colour_};
    while (!(have_depth && have_colour)) {
      int ready = -1;
      const openni::Status status =
          openni::OpenNI::waitForAnyStream(streams, 2, &ready, kWaitStepMs);
      if (status == openni::STATUS_OK && ready >= 0) {
        openni::VideoFrameRef& target = ready == 0 ? depth_frame_ : colour_frame_;
        if (streams[ready]->readFrame(&target) != openni::STATUS_OK) {
          return lose(std::string("readFrame failed: ") + openni::OpenNI::getExtendedError());
        }
        (ready == 0 ? have_depth : have_colour) = true;
      } else if (status != openni::STATUS_TIME_OUT) {
        return lose(std::string("waitForAnyStream failed: ") + openni::OpenNI::getExtendedError());
      }
      if (std::chrono::steady_clock::now() > deadline) {
        if (is_file_) {
          end_of_file_ = true;
          error_ = name_ + ": end of the recording";
          return FrameStatus::kEndOfStream;
        }
        return lose("no synchronised frame pair for " +
                    std::to_string(options_.frame_timeout_ns / 1'000'000) + " ms");
      }
    }
    if (!convert(frame)) return FrameStatus::kNoFrame;
    error_.clear();
    return FrameStatus::kFrame;
  }

  [[nodiscard]] geometry::PinholeCamera camera() const override { return camera_.pinhole(); }
  [[nodiscard]] std::string describe() const override {
    return name_ + " (" + (is_file_ ? "OpenNI2 recording" : "OpenNI2 device") + ", " +
           std::to_string(options_.width) + "x" + std::to_string(options_.height) + "@" +
           std::to_string(options_.fps) + ", depth registered to colour), intrinsics from " +
           intrinsics_from_;
  }
  [[nodiscard]] bool connected() const override { return open_; }

 private:
  bool has_fov_intrinsics() const {
    const float h = colour_.getHorizontalFieldOfView(), v = colour_.getVerticalFieldOfView();
    return std::isfinite(h) && std::isfinite(v) && h > 0.1f && h < 3.0f && v > 0.1f && v < 3.0f;
  }

  // The colour stream's field of view gives the pinhole focal lengths, f = (size/2)/tan(fov/2);
  // registered depth shares the colour camera, and OpenNI2 reports no principal point or lens
  // distortion, so the centre and no distortion are assumed.
  config::CameraInfo fov_intrinsics() {
    config::CameraInfo info;
    info.name = "openni2_fov";
    info.width = options_.width;
    info.height = options_.height;
    info.fx =
        0.5 * info.width / std::tan(0.5 * static_cast<double>(colour_.getHorizontalFieldOfView()));
    info.fy =
        0.5 * info.height / std::tan(0.5 * static_cast<double>(colour_.getVerticalFieldOfView()));
    info.cx = 0.5 * (info.width - 1);
    info.cy = 0.5 * (info.height - 1);
    info.distortion.assign(5, 0.0);
    info.depth_scale_units_per_m = 1000.0;
    intrinsics_from_ = "the device's field of view";
    return info;
  }

  /// The mode of `sensor` with this size, rate and an accepted pixel format, or a reason.
  bool pick_mode(openni::SensorType sensor, bool depth, openni::VideoMode& chosen,
                 std::string& why) {
    const openni::SensorInfo* info = device_.getSensorInfo(sensor);
    const char* what = depth ? "depth" : "colour";
    if (info == nullptr) {
      why = name_ + ": the device has no " + what + " sensor";
      return false;
    }
    const openni::Array<openni::VideoMode>& modes = info->getSupportedVideoModes();
    std::string offered;
    for (int i = 0; i < modes.getSize(); ++i) {
      const openni::VideoMode& m = modes[i];
      const bool format_ok = depth ? m.getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_1_MM
                                   : m.getPixelFormat() == openni::PIXEL_FORMAT_RGB888;
      if (!format_ok) continue;
      offered += (offered.empty() ? "" : ", ") + mode_text(m);
      if (m.getResolutionX() == options_.width && m.getResolutionY() == options_.height &&
          m.getFps() == options_.fps) {
        chosen = m;
        return true;
      }
    }
    why = name_ + ": " + what + " mode " + std::to_string(options_.width) + "x" +
          std::to_string(options_.height) + "@" + std::to_string(options_.fps) +
          " is not offered; the device offers " + (offered.empty() ? "none" : offered);
    return false;
  }

  bool open_device(std::string& why) {
    if (device_.open(uri_.empty() ? openni::ANY_DEVICE : uri_.c_str()) != openni::STATUS_OK) {
      // Read the reason first: enumerateDevices() clears OpenNI2's extended error.
      std::string detail = openni::OpenNI::getExtendedError();
      openni::Array<openni::DeviceInfo> devices;
      openni::OpenNI::enumerateDevices(&devices);
      std::string list;
      for (int i = 0; i < devices.getSize(); ++i) {
        list += (list.empty() ? "" : ", ") + std::string(devices[i].getUri());
      }
      while (!detail.empty() && std::isspace(static_cast<unsigned char>(detail.back()))) {
        detail.pop_back();
      }
      while (!detail.empty() && std::isspace(static_cast<unsigned char>(detail.front()))) {
        detail.erase(0, 1);
      }
      why = name_ + ": cannot open (" + detail +
            "); OpenNI2 devices connected: " + (list.empty() ? "none" : list);
      return false;
    }
    if (!start_streams(why)) {
      close_device();
      return false;
    }
    open_ = true;
    clock_.reset();
    return true;
  }

  bool start_streams(std::string& why) {
    if (depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK ||
        colour_.create(device_, openni::SENSOR_COLOR) != openni::STATUS_OK) {
      why = name_ +
            ": cannot create the depth and colour streams: " + openni::OpenNI::getExtendedError();
      return false;
    }
    if (is_file_) {
      // A recording plays back the modes it was made with; check them instead of setting them.
      const openni::VideoMode d = depth_.getVideoMode(), c = colour_.getVideoMode();
      if (!is_depth_format(d.getPixelFormat()) ||
          c.getPixelFormat() != openni::PIXEL_FORMAT_RGB888 ||
          d.getResolutionX() != options_.width || d.getResolutionY() != options_.height ||
          c.getResolutionX() != options_.width || c.getResolutionY() != options_.height) {
        why = name_ + ": recorded depth " + mode_text(d) + " and colour " + mode_text(c) +
              ", expected both " + std::to_string(options_.width) + "x" +
              std::to_string(options_.height) + " (depth in mm, colour RGB888)";
        return false;
      }
    } else {
      openni::VideoMode depth_mode, colour_mode;
      if (!pick_mode(openni::SENSOR_DEPTH, true, depth_mode, why) ||
          !pick_mode(openni::SENSOR_COLOR, false, colour_mode, why)) {
        return false;
      }
      if (depth_.setVideoMode(depth_mode) != openni::STATUS_OK ||
          colour_.setVideoMode(colour_mode) != openni::STATUS_OK) {
        why = name_ + ": the device refused mode " + mode_text(depth_mode) + ": " +
              openni::OpenNI::getExtendedError();
        return false;
      }
      if (!device_.isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) ||
          device_.setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR) !=
              openni::STATUS_OK) {
        why = name_ + ": the device cannot register depth to colour";
        return false;
      }
      // Without sync the two streams drift apart by up to a frame period (33 ms at 30 Hz).
      device_.setDepthColorSyncEnabled(true);
    }
    if (depth_.start() != openni::STATUS_OK || colour_.start() != openni::STATUS_OK) {
      why = name_ + ": cannot start the streams: " + openni::OpenNI::getExtendedError();
      return false;
    }
    return true;
  }

  bool convert(RgbdFrame& frame) {
    const int w = options_.width, h = options_.height;
    if (depth_frame_.getWidth() != w || depth_frame_.getHeight() != h ||
        colour_frame_.getWidth() != w || colour_frame_.getHeight() != h) {
      error_ = name_ + ": frame of unexpected size (cropping enabled on the device?)";
      return false;
    }
    const cv::Mat rgb(h, w, CV_8UC3, const_cast<void*>(colour_frame_.getData()),
                      static_cast<std::size_t>(colour_frame_.getStrideInBytes()));
    cv::cvtColor(rgb, bgr_raw_, cv::COLOR_RGB2BGR);
    const cv::Mat depth(h, w, CV_16UC1, const_cast<void*>(depth_frame_.getData()),
                        static_cast<std::size_t>(depth_frame_.getStrideInBytes()));
    const double m_per_unit =
        depth_frame_.getVideoMode().getPixelFormat() == openni::PIXEL_FORMAT_DEPTH_100_UM ? 1e-4
                                                                                          : 1e-3;
    depth.convertTo(depth_m_raw_, CV_32F, m_per_unit);  // 0 (no depth) stays 0
    undistorter_->apply_color(bgr_raw_, frame.bgr);
    undistorter_->apply_depth(depth_m_raw_, frame.depth_m);
    cv::cvtColor(frame.bgr, frame.gray, cv::COLOR_BGR2GRAY);
    frame.t_ns = clock_.to_ns(colour_frame_.getTimestamp());
    frame.depth_t_ns = clock_.to_ns(depth_frame_.getTimestamp());
    return true;
  }

  FrameStatus lose(const std::string& why) {
    close_device();
    error_ = reconnect_.lost(why);
    return FrameStatus::kNoFrame;
  }

  void close_device() {
    depth_frame_.release();
    colour_frame_.release();
    depth_.stop();
    colour_.stop();
    depth_.destroy();
    colour_.destroy();
    if (device_.isValid()) device_.close();
    open_ = false;
  }

  std::string uri_;
  std::string name_;
  CameraSourceOptions options_;
  bool is_file_;
  bool initialized_ = false;
  bool open_ = false;
  bool end_of_file_ = false;
  std::string intrinsics_from_;
  config::CameraInfo camera_;
  std::optional<config::Undistorter> undistorter_;
  DeviceClock clock_;
  Reconnector reconnect_;
  openni::Device device_;
  openni::VideoStream depth_, colour_;
  openni::VideoFrameRef depth_frame_, colour_frame_;
  cv::Mat bgr_raw_, depth_m_raw_;
};

}  // namespace

std::unique_ptr<CameraSource> open_openni2(const std::string& uri,
                                           const CameraSourceOptions& options) {
  return std::make_unique<Openni2FrameSource>(uri, options);
}

}  // namespace hq::sources::detail
