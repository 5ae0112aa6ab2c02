#include "hq/sources/tum_recorder.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"

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

/// A plain TUM recording (images, lists, accelerometer) labelled with where it came from.
TumRecordingOptions labelled(const std::string& description) {
  TumRecordingOptions options;
  options.description = description;
  return options;
}

}  // namespace

std::string TumRecorder::stamp(std::int64_t t_ns) {
  const bool negative = t_ns < 0;
  const std::int64_t us = ((negative ? -t_ns : t_ns) + 500) / 1000;
  char text[40];
  hq::format_into(text, "{}{}.{:06}", negative ? "-" : "", us / 1000000, us % 1000000);
  return text;
}

TumRecorder::TumRecorder(const std::string& dir, const geometry::PinholeCamera& camera,
                         const std::string& description)
    : TumRecorder(dir, camera, labelled(description)) {}

TumRecorder::TumRecorder(const std::string& dir, const geometry::PinholeCamera& camera,
                         const TumRecordingOptions& options)
    : dir_(dir) {
  if (!options.replace_existing && std::filesystem::exists(dir_ + "/rgb.txt")) {
    throw InputError(dir_ + "/rgb.txt: exists already; record into a new directory");
  }
  std::error_code error;
  std::filesystem::create_directories(dir_ + "/rgb", error);
  if (!error) std::filesystem::create_directories(dir_ + "/depth", error);
  if (error)
    throw InputError(dir_ + ": cannot create the recording directories: " + error.message());
  const std::string from = "# file: '" + options.description + "'";
  open_list(rgb_, dir_ + "/rgb.txt", "# color images\n" + from + "\n# timestamp filename\n");
  open_list(depth_, dir_ + "/depth.txt", "# depth maps\n" + from + "\n# timestamp filename\n");
  if (options.ground_truth) {
    open_list(groundtruth_, dir_ + "/groundtruth.txt",
              "# ground truth trajectory\n" + from + "\n# timestamp tx ty tz qx qy qz qw\n");
  }
  open_list(accelerometer_, dir_ + "/accelerometer.txt",
            "# accelerometer data\n" + from + options.accel_note + "\n# timestamp ax ay az\n");
  if (options.gyro) {
    open_list(gyro_, dir_ + "/gyro.txt",
              "# gyroscope data\n" + from + options.gyro_note + "\n# timestamp wx wy wz\n");
  }
  std::ofstream info(dir_ + "/camera.yaml");
  info << "# Intrinsics of the recorded (already undistorted) images, from " << options.description
       << "\nimage_width: " << camera.width << "\nimage_height: " << camera.height
       << "\ncamera_name: " << options.camera_name << "\ncamera_matrix: {rows: 3, cols: 3, data: ["
       << camera.fx << ", 0, " << camera.cx << ", 0, " << camera.fy << ", " << camera.cy
       << ", 0, 0, 1]}\ndistortion_model: plumb_bob\n"
       << "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n"
       << "depth_scale_units_per_m: 5000\n"
       << options.camera_comment;
  if (!info) throw InputError(dir_ + "/camera.yaml: cannot write");
}

void TumRecorder::write_frame(const RgbdFrame& frame) {
  write_frame(frame.t_ns, frame.depth_exposure_ns(), frame.bgr, frame.depth_m);
}

void TumRecorder::write_frame(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m) {
  write_frame(t_ns, t_ns, image, depth_m);
}

void TumRecorder::write_frame(std::int64_t t_ns, std::int64_t depth_t_ns, const cv::Mat& image,
                              const cv::Mat& depth_m) {
  const std::string t = stamp(t_ns);
  const std::string t_depth = stamp(depth_t_ns);
  const std::string rgb_name = "rgb/" + t + ".png";
  const std::string depth_name = "depth/" + t_depth + ".png";
  depth_m.convertTo(depth_u16_, CV_16U, kDepthUnitsPerM);  // rounds and saturates
  if (!cv::imwrite(dir_ + "/" + rgb_name, image)) {
    throw InputError(dir_ + "/" + rgb_name + ": cannot write");
  }
  if (!cv::imwrite(dir_ + "/" + depth_name, depth_u16_)) {
    throw InputError(dir_ + "/" + depth_name + ": cannot write");
  }
  rgb_ << t << ' ' << rgb_name << '\n';
  depth_ << t_depth << ' ' << depth_name << '\n';
  ++frames_;
}

void TumRecorder::write_accel(const recording::AccelSample& sample) {
  char line[160];
  hq::format_into(line, "{} {:.6f} {:.6f} {:.6f}\n", stamp(sample.t_ns).c_str(),
                  sample.accel_mps2.x(), sample.accel_mps2.y(), sample.accel_mps2.z());
  accelerometer_ << line;
}

void TumRecorder::write_gyro(std::int64_t t_ns, const Eigen::Vector3d& omega_radps) {
  char line[160];
  hq::format_into(line, "{} {:.6f} {:.6f} {:.6f}\n", stamp(t_ns).c_str(), omega_radps.x(),
                  omega_radps.y(), omega_radps.z());
  gyro_ << line;
}

void TumRecorder::write_ground_truth(std::int64_t t_ns, const Eigen::Isometry3d& T_G_C) {
  const Eigen::Quaterniond q(T_G_C.linear());
  const Eigen::Vector3d& p = T_G_C.translation();
  char line[256];
  hq::format_into(line, "{} {:.6f} {:.6f} {:.6f} {:.6f} {:.6f} {:.6f} {:.6f}\n",
                  stamp(t_ns).c_str(), p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
  groundtruth_ << line;
}

void TumRecorder::close() {
  for (std::ofstream* f : {&rgb_, &depth_, &accelerometer_, &gyro_, &groundtruth_}) {
    if (!f->is_open()) continue;
    f->flush();
    if (!*f) throw InputError(dir_ + ": writing the recording lists failed");
    f->close();
  }
}

}  // namespace hq::sources
