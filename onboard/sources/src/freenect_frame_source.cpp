#include "freenect_frame_source.hpp"

#include "hq/base/error.hpp"

#include "camera_common.hpp"
#include <opencv2/imgproc.hpp>

#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <dlfcn.h>
#include <filesystem>
#include <fstream>
#include <libfreenect.h>
#include <optional>
#include <string>
#include <sys/time.h>

namespace hq::sources::detail {

namespace {

constexpr int kWidth = 640;  // the only size at which libfreenect registers depth to RGB
constexpr int kHeight = 480;
constexpr int kFps = 30;
constexpr std::int64_t kNsPerTickNum = 50;  // Kinect frame clock: 60 MHz, 1e9/60e6 = 50/3 ns
constexpr std::int64_t kNsPerTickDen = 3;
constexpr int kTickBits = 32;
constexpr int kInvalidRaw11 = 2047;
// Raw 11-bit disparity to metres, z = 1 / (a * raw + b): N. Burrus's fit for the Kinect v1 as
// given on the OpenKinect wiki ("Imaging Information"). Only used for fakenect dumps, whose
// depth is the unregistered 11-bit stream (fakenect offers no other depth format).
constexpr double kRaw11A = -0.0030711016;
constexpr double kRaw11B = 3.3309495161;
constexpr const char* kFakenectPathVar = "FAKENECT_PATH";

/// True if the libfreenect loaded into this process is fakenect (Debian libfreenect-bin
/// installs it under .../fakenect/), which replays a dump instead of talking USB.
bool running_on_fakenect() {
  void* symbol = dlsym(RTLD_DEFAULT, "freenect_init");
  Dl_info info{};
  if (symbol == nullptr || dladdr(symbol, &info) == 0 || info.dli_fname == nullptr) return false;
  return std::strstr(info.dli_fname, "/fakenect/") != nullptr;
}

/// fakenect exit()s or asserts on a missing or malformed dump, so the dump is checked before
/// fakenect reads it: INDEX.txt lines name r-<t>-<ticks>.ppm (P6 header line, 640x480x3 bytes),
/// d-<t>-<ticks>.pgm (P5 header line, 640x480 host-endian uint16) and a-<t>-<ticks>.dump
/// (a freenect_raw_tilt_state), as fakenect-record writes them.
void check_fakenect_dump() {
  const char* dir = std::getenv(kFakenectPathVar);
  if (dir == nullptr || *dir == '\0') {
    throw InputError(std::string("fakenect: ") + kFakenectPathVar +
                     " is not set; set it to a dump directory written by fakenect-record");
  }
  const std::string index_path = std::string(dir) + "/INDEX.txt";
  std::ifstream index(index_path);
  if (!index) throw InputError(index_path + ": cannot open the fakenect dump index");
  std::string line;
  int line_number = 0, colour = 0, depth = 0;
  while (std::getline(index, line)) {
    ++line_number;
    const std::string where = index_path + ":" + std::to_string(line_number);
    char type = 0;
    double t_s = 0.0;
    unsigned ticks = 0;
    if (std::sscanf(line.c_str(), "%c-%lf-%u", &type, &t_s, &ticks) != 3 ||
        (type != 'r' && type != 'd' && type != 'a')) {
      throw InputError(where + ": '" + line + "', expected r-|d-|a-<seconds>-<ticks>.<ext>");
    }
    const std::string path = std::string(dir) + "/" + line;
    std::ifstream file(path, std::ios::binary);
    if (!file) throw InputError(where + ": " + path + " is missing");
    const auto size = static_cast<std::size_t>(std::filesystem::file_size(path));
    if (type == 'a') {
      if (size != sizeof(freenect_raw_tilt_state)) {
        throw InputError(path + ": " + std::to_string(size) + " bytes, expected " +
                         std::to_string(sizeof(freenect_raw_tilt_state)) +
                         " (one freenect_raw_tilt_state)");
      }
      continue;
    }
    std::string header;
    std::getline(file, header);
    const char* magic = type == 'r' ? "P6" : "P5";
    const std::size_t payload = type == 'r' ? kWidth * kHeight * 3 : kWidth * kHeight * 2;
    if (!file || header.rfind(magic, 0) != 0 || size != header.size() + 1 + payload) {
      throw InputError(path + ": expected a '" + magic + " ...' header line and " +
                       std::to_string(payload) + " bytes of 640x480 " +
                       (type == 'r' ? "RGB" : "11-bit depth") + ", found " + std::to_string(size) +
                       " bytes in all");
    }
    (type == 'r' ? colour : depth)++;
  }
  if (colour == 0 || depth == 0) {
    throw InputError(index_path + ": lists " + std::to_string(colour) + " colour and " +
                     std::to_string(depth) + " depth frames, expected at least one of each");
  }
}

class FreenectFrameSource final : public CameraSource {
 public:
  FreenectFrameSource(int index, const CameraSourceOptions& options)
      : index_(index),
        name_("freenect:" + std::to_string(index)),
        options_(options),
        camera_(load_camera_for(options, "calib/kinect_v1.yaml", name_)),
        undistorter_(camera_),
        fakenect_(running_on_fakenect()),
        clock_(kNsPerTickNum, kNsPerTickDen, kTickBits),
        reconnect_(name_, options.retry_interval_ns) {
    if (fakenect_) check_fakenect_dump();
    video_rgb_.create(kHeight, kWidth, CV_8UC3);
    depth_raw_.create(kHeight, kWidth, CV_16UC1);
    bgr_raw_.create(kHeight, kWidth, CV_8UC3);
    depth_m_raw_.create(kHeight, kWidth, CV_32FC1);
    for (int raw = 0; raw < static_cast<int>(raw11_to_m_.size()); ++raw) {
      const double inverse_z = kRaw11A * raw + kRaw11B;
      raw11_to_m_[static_cast<std::size_t>(raw)] =
          raw < kInvalidRaw11 && inverse_z > 0.0 ? static_cast<float>(1.0 / inverse_z) : 0.0f;
    }
    std::string why;
    if (!open_device(why)) {
      // A fakenect dump that does not open stays broken; a Kinect may be plugged in yet.
      if (fakenect_) throw InputError(why);
      throw DeviceUnavailableError(why);
    }
  }

  ~FreenectFrameSource() override { close_device(); }
  FreenectFrameSource(const FreenectFrameSource&) = delete;
  FreenectFrameSource& operator=(const FreenectFrameSource&) = delete;

  FrameStatus next(RgbdFrame& frame) override {
    if (end_of_dump_) return FrameStatus::kEndOfStream;
    if (device_ == nullptr &&
        !reconnect_.reopen([this](std::string& why) { return open_device(why); }, error_)) {
      return FrameStatus::kNoFrame;
    }
    const auto deadline =
        std::chrono::steady_clock::now() + std::chrono::nanoseconds(options_.frame_timeout_ns);
    while (!(video_new_ && depth_new_)) {
      timeval timeout{0, 100'000};
      const int status = freenect_process_events_timeout(context_, &timeout);
      if (status < 0) {
        if (fakenect_) {
          end_of_dump_ = true;
          error_ = "fakenect: end of the dump in " + std::string(std::getenv(kFakenectPathVar));
          return FrameStatus::kEndOfStream;
        }
        return lose("freenect_process_events failed (" + std::to_string(status) +
                    "): device unplugged?");
      }
      if (std::chrono::steady_clock::now() > deadline) {
        return lose("no RGB-D frame pair for " +
                    std::to_string(options_.frame_timeout_ns / 1'000'000) + " ms");
      }
    }
    video_new_ = depth_new_ = false;
    frame.t_ns = clock_.to_ns(video_ticks_);
    frame.depth_t_ns = clock_.to_ns(depth_ticks_);
    cv::cvtColor(video_rgb_, bgr_raw_, cv::COLOR_RGB2BGR);
    convert_depth();
    undistorter_.apply_color(bgr_raw_, frame.bgr);
    undistorter_.apply_depth(depth_m_raw_, frame.depth_m);
    cv::cvtColor(frame.bgr, frame.gray, cv::COLOR_BGR2GRAY);
    read_accelerometer(frame.t_ns);
    error_.clear();
    return FrameStatus::kFrame;
  }

  [[nodiscard]] geometry::PinholeCamera camera() const override { return camera_.pinhole(); }

  [[nodiscard]] std::string describe() const override {
    return name_ +
           (fakenect_ ? " (fakenect replay of " + std::string(std::getenv(kFakenectPathVar)) +
                            ", 11-bit depth converted to metres, unregistered)"
                      : " (Kinect v1, 640x480@30, depth registered to RGB)") +
           ", intrinsics " +
           (options_.camera_file.empty() ? "calib/kinect_v1.yaml" : options_.camera_file);
  }

  [[nodiscard]] std::optional<recording::AccelSample> accelerometer() const override {
    return accel_;
  }
  [[nodiscard]] bool connected() const override { return device_ != nullptr; }

 private:
  static void on_video(freenect_device* device, void* data, uint32_t ticks) {
    auto* self = static_cast<FreenectFrameSource*>(freenect_get_user(device));
    std::memcpy(self->video_rgb_.data, data, kWidth * kHeight * 3);
    self->video_ticks_ = ticks;
    self->video_new_ = true;
  }

  static void on_depth(freenect_device* device, void* data, uint32_t ticks) {
    auto* self = static_cast<FreenectFrameSource*>(freenect_get_user(device));
    std::memcpy(self->depth_raw_.data, data, kWidth * kHeight * 2);
    self->depth_ticks_ = ticks;
    self->depth_new_ = true;
  }

  void convert_depth() {
    for (int v = 0; v < kHeight; ++v) {
      const auto* raw = depth_raw_.ptr<std::uint16_t>(v);
      auto* z_m = depth_m_raw_.ptr<float>(v);
      for (int u = 0; u < kWidth; ++u) {
        // Registered depth is in millimetres, 0 = none; the 11-bit stream goes through the LUT.
        z_m[u] = fakenect_ ? (raw[u] < raw11_to_m_.size() ? raw11_to_m_[raw[u]] : 0.0f)
                           : static_cast<float>(raw[u]) * 1e-3f;
      }
    }
  }

  void read_accelerometer(std::int64_t t_ns) {
    if (!has_motor_ || freenect_update_tilt_state(device_) < 0) return;
    freenect_raw_tilt_state* state = freenect_get_tilt_state(device_);
    if (state == nullptr) return;
    double x = 0.0, y = 0.0, z = 0.0;
    freenect_get_mks_accel(state, &x, &y, &z);
    accel_ = recording::AccelSample{t_ns, Eigen::Vector3d(x, y, z)};
  }

  FrameStatus lose(const std::string& why) {
    close_device();
    error_ = reconnect_.lost(why);
    return FrameStatus::kNoFrame;
  }

  bool open_device(std::string& why) {
    if (freenect_init(&context_, nullptr) < 0) {
      context_ = nullptr;
      why = name_ + ": freenect_init failed (libusb could not start)";
      return false;
    }
    freenect_set_log_level(context_, FREENECT_LOG_FATAL);
    const int count = freenect_num_devices(context_);
    if (index_ >= count) {
      why = name_ + ": no Kinect at index " + std::to_string(index_) + " (" +
            std::to_string(count < 0 ? 0 : count) +
            " found; is it plugged in and powered, and readable by this user through the "
            "udev rule of libfreenect0.5?)";
      close_device();
      return false;
    }
    // The motor subdevice carries the accelerometer; some Kinects (model 1473) only expose it
    // with audio firmware loaded, so fall back to the camera alone.
    has_motor_ = true;
    freenect_select_subdevices(context_, static_cast<freenect_device_flags>(FREENECT_DEVICE_CAMERA |
                                                                            FREENECT_DEVICE_MOTOR));
    if (freenect_open_device(context_, &device_, index_) < 0) {
      has_motor_ = false;
      freenect_select_subdevices(context_, FREENECT_DEVICE_CAMERA);
      if (freenect_open_device(context_, &device_, index_) < 0) {
        device_ = nullptr;
        why = name_ + ": freenect_open_device failed (busy in another program, or no permission)";
        close_device();
        return false;
      }
    }
    const freenect_frame_mode video =
        freenect_find_video_mode(FREENECT_RESOLUTION_MEDIUM, FREENECT_VIDEO_RGB);
    const freenect_frame_mode depth = freenect_find_depth_mode(
        FREENECT_RESOLUTION_MEDIUM, fakenect_ ? FREENECT_DEPTH_11BIT : FREENECT_DEPTH_REGISTERED);
    if (!video.is_valid || !depth.is_valid || freenect_set_video_mode(device_, video) < 0 ||
        freenect_set_depth_mode(device_, depth) < 0) {
      why = name_ + ": the device refused 640x480 RGB with registered depth";
      close_device();
      return false;
    }
    freenect_set_user(device_, this);
    freenect_set_video_callback(device_, &FreenectFrameSource::on_video);
    freenect_set_depth_callback(device_, &FreenectFrameSource::on_depth);
    if (freenect_start_video(device_) < 0 || freenect_start_depth(device_) < 0) {
      why = name_ + ": could not start the RGB and depth streams";
      close_device();
      return false;
    }
    video_new_ = depth_new_ = false;
    clock_.reset();
    return true;
  }

  void close_device() {
    if (device_ != nullptr) {
      freenect_stop_depth(device_);
      freenect_stop_video(device_);
      freenect_close_device(device_);
      device_ = nullptr;
    }
    if (context_ != nullptr) {
      freenect_shutdown(context_);
      context_ = nullptr;
    }
  }

  int index_;
  std::string name_;
  CameraSourceOptions options_;
  config::CameraInfo camera_;
  config::Undistorter undistorter_;
  bool fakenect_;
  DeviceClock clock_;
  Reconnector reconnect_;
  freenect_context* context_ = nullptr;
  freenect_device* device_ = nullptr;
  bool has_motor_ = false;
  bool end_of_dump_ = false;
  bool video_new_ = false, depth_new_ = false;
  std::uint32_t video_ticks_ = 0;
  std::uint32_t depth_ticks_ = 0;
  cv::Mat video_rgb_, depth_raw_, bgr_raw_, depth_m_raw_;
  std::array<float, 2048> raw11_to_m_{};
  std::optional<recording::AccelSample> accel_;
};

}  // namespace

std::unique_ptr<CameraSource> open_freenect(int index, const CameraSourceOptions& options) {
  if (options.width != kWidth || options.height != kHeight || options.fps != kFps) {
    throw InputError("freenect:" + std::to_string(index) + ": mode " +
                     std::to_string(options.width) + "x" + std::to_string(options.height) + "@" +
                     std::to_string(options.fps) +
                     " is not offered: the Kinect v1 registers depth to RGB only at 640x480@30");
  }
  return std::make_unique<FreenectFrameSource>(index, options);
}

}  // namespace hq::sources::detail
