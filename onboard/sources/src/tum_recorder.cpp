#include "hq/sources/tum_recorder.hpp"

#include "hq/base/error.hpp"

#include <opencv2/imgcodecs.hpp>

#include <cinttypes>
#include <cstdio>
#include <filesystem>

namespace hq::sources {

namespace {

constexpr double kDepthUnitsPerM = 5000.0;  // TUM RGB-D: depth PNG value / 5000 = metres

void open_list(std::ofstream& file, const std::string& path, const std::string& header) {
  file.open(path);
  if (!file) throw InputError(path + ": cannot open for writing");
  file << header;
}

}  // namespace

std::string TumRecorder::stamp(std::int64_t t_ns) {
  const bool negative = t_ns < 0;
  const std::int64_t us = ((negative ? -t_ns : t_ns) + 500) / 1000;
  char text[40];
  std::snprintf(text, sizeof(text), "%s%" PRId64 ".%06" PRId64, negative ? "-" : "", us / 1000000,
                us % 1000000);
  return text;
}

TumRecorder::TumRecorder(const std::string& dir, const geometry::PinholeCamera& camera,
                         const std::string& description)
    : dir_(dir) {
  if (std::filesystem::exists(dir_ + "/rgb.txt")) {
    throw InputError(dir_ + "/rgb.txt: exists already; record into a new directory");
  }
  std::error_code error;
  std::filesystem::create_directories(dir_ + "/rgb", error);
  if (!error) std::filesystem::create_directories(dir_ + "/depth", error);
  if (error)
    throw InputError(dir_ + ": cannot create the recording directories: " + error.message());
  const std::string from = "# file: '" + description + "'\n";
  open_list(rgb_, dir_ + "/rgb.txt", "# color images\n" + from + "# timestamp filename\n");
  open_list(depth_, dir_ + "/depth.txt", "# depth maps\n" + from + "# timestamp filename\n");
  open_list(accelerometer_, dir_ + "/accelerometer.txt",
            "# accelerometer data\n" + from + "# timestamp ax ay az\n");
  std::ofstream info(dir_ + "/camera.yaml");
  info << "# Intrinsics of the recorded (already undistorted) images, from " << description
       << "\nimage_width: " << camera.width << "\nimage_height: " << camera.height
       << "\ncamera_name: hq_record\ncamera_matrix: {rows: 3, cols: 3, data: [" << camera.fx
       << ", 0, " << camera.cx << ", 0, " << camera.fy << ", " << camera.cy
       << ", 0, 0, 1]}\ndistortion_model: plumb_bob\n"
       << "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n"
       << "depth_scale_units_per_m: 5000\n";
  if (!info) throw InputError(dir_ + "/camera.yaml: cannot write");
}

void TumRecorder::write_frame(const RgbdFrame& frame) {
  const std::string t = stamp(frame.t_ns);
  const std::string rgb_name = "rgb/" + t + ".png";
  const std::string depth_name = "depth/" + t + ".png";
  frame.depth_m.convertTo(depth_u16_, CV_16U, kDepthUnitsPerM);  // rounds and saturates
  if (!cv::imwrite(dir_ + "/" + rgb_name, frame.bgr)) {
    throw InputError(dir_ + "/" + rgb_name + ": cannot write");
  }
  if (!cv::imwrite(dir_ + "/" + depth_name, depth_u16_)) {
    throw InputError(dir_ + "/" + depth_name + ": cannot write");
  }
  rgb_ << t << ' ' << rgb_name << '\n';
  depth_ << t << ' ' << depth_name << '\n';
  ++frames_;
}

void TumRecorder::write_accel(const recording::AccelSample& sample) {
  char line[160];
  std::snprintf(line, sizeof(line), "%s %.6f %.6f %.6f\n", stamp(sample.t_ns).c_str(),
                sample.accel_mps2.x(), sample.accel_mps2.y(), sample.accel_mps2.z());
  accelerometer_ << line;
}

void TumRecorder::close() {
  for (std::ofstream* f : {&rgb_, &depth_, &accelerometer_}) {
    f->flush();
    if (!*f) throw InputError(dir_ + ": writing the recording lists failed");
    f->close();
  }
}

}  // namespace hq::sources
