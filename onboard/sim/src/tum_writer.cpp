#include "hq/sim/tum_writer.hpp"

#include "hq/base/error.hpp"

#include <opencv2/imgcodecs.hpp>

#include <cinttypes>
#include <cstdio>
#include <filesystem>

namespace hq::sim {

namespace {
constexpr double kDepthUnitsPerM = 5000.0;  // TUM RGB-D: depth PNG value / 5000 = metres

void open_list(std::ofstream& file, const std::string& path, const char* header) {
  file.open(path);
  if (!file) throw InputError(path + ": cannot open for writing");
  file << header;
}
}  // namespace

std::string TumWriter::stamp(std::int64_t t_ns) {
  const bool negative = t_ns < 0;
  const std::int64_t magnitude = negative ? -t_ns : t_ns;
  // Round to microseconds in integers so that file names and list entries agree exactly.
  const std::int64_t us = (magnitude + 500) / 1000;
  char text[40];
  std::snprintf(text, sizeof(text), "%s%" PRId64 ".%06" PRId64, negative ? "-" : "", us / 1000000,
                us % 1000000);
  return text;
}

TumWriter::TumWriter(const std::string& dir, const geometry::PinholeCamera& camera,
                     const Eigen::Isometry3d& T_body_camera)
    : dir_(dir) {
  std::error_code error;
  std::filesystem::create_directories(dir_ + "/rgb", error);
  if (!error) std::filesystem::create_directories(dir_ + "/depth", error);
  if (error)
    throw InputError(dir_ + ": cannot create the recording directories: " + error.message());
  open_list(rgb_, dir_ + "/rgb.txt", "# color images\n# file: 'hq-sim'\n# timestamp filename\n");
  open_list(depth_, dir_ + "/depth.txt", "# depth maps\n# file: 'hq-sim'\n# timestamp filename\n");
  open_list(groundtruth_, dir_ + "/groundtruth.txt",
            "# ground truth trajectory\n# file: 'hq-sim'\n# timestamp tx ty tz qx qy qz qw\n");
  open_list(accelerometer_, dir_ + "/accelerometer.txt",
            "# accelerometer data\n# file: 'hq-sim' (specific force, body NED frame, m/s^2)\n"
            "# timestamp ax ay az\n");
  open_list(gyro_, dir_ + "/gyro.txt",
            "# gyroscope data\n# file: 'hq-sim' (body NED frame, rad/s)\n"
            "# timestamp wx wy wz\n");

  std::ofstream info(dir_ + "/camera.yaml");
  if (!info) throw InputError(dir_ + "/camera.yaml: cannot open for writing");
  const Eigen::Quaterniond q(T_body_camera.linear());
  const Eigen::Vector3d& p = T_body_camera.translation();
  info << "image_width: " << camera.width << "\nimage_height: " << camera.height
       << "\ncamera_name: hq_sim\ncamera_matrix: {rows: 3, cols: 3, data: [" << camera.fx << ", 0, "
       << camera.cx << ", 0, " << camera.fy << ", " << camera.cy
       << ", 0, 0, 1]}\ndistortion_model: plumb_bob\n"
       << "distortion_coefficients: {rows: 1, cols: 5, data: [0, 0, 0, 0, 0]}\n"
       << "depth_scale_units_per_m: 5000\n"
       << "# T_body_camera (body NED, camera optical): p_body_camera_m and q_body_camera xyzw\n"
       << "# p_body_camera_m: [" << p.x() << ", " << p.y() << ", " << p.z() << "]\n"
       << "# q_body_camera_xyzw: [" << q.x() << ", " << q.y() << ", " << q.z() << ", " << q.w()
       << "]\n";
}

void TumWriter::write_frame(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m,
                            const Eigen::Isometry3d& T_world_camera) {
  const std::string t = stamp(t_ns);
  const std::string rgb_name = "rgb/" + t + ".png";
  const std::string depth_name = "depth/" + t + ".png";
  depth_m.convertTo(depth_u16_, CV_16U, kDepthUnitsPerM);  // rounds and saturates
  if (!cv::imwrite(dir_ + "/" + rgb_name, image)) {
    throw InputError(dir_ + "/" + rgb_name + ": cannot write");
  }
  if (!cv::imwrite(dir_ + "/" + depth_name, depth_u16_)) {
    throw InputError(dir_ + "/" + depth_name + ": cannot write");
  }
  rgb_ << t << ' ' << rgb_name << '\n';
  depth_ << t << ' ' << depth_name << '\n';
  const Eigen::Quaterniond q(T_world_camera.linear());
  const Eigen::Vector3d& p = T_world_camera.translation();
  char line[256];
  std::snprintf(line, sizeof(line), "%s %.6f %.6f %.6f %.6f %.6f %.6f %.6f\n", t.c_str(), p.x(),
                p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
  groundtruth_ << line;
}

void TumWriter::write_imu(const ImuSample& sample) {
  const std::string t = stamp(sample.t_ns);
  char line[256];
  std::snprintf(line, sizeof(line), "%s %.6f %.6f %.6f\n", t.c_str(), sample.f_body_mps2.x(),
                sample.f_body_mps2.y(), sample.f_body_mps2.z());
  accelerometer_ << line;
  std::snprintf(line, sizeof(line), "%s %.6f %.6f %.6f\n", t.c_str(), sample.omega_body_radps.x(),
                sample.omega_body_radps.y(), sample.omega_body_radps.z());
  gyro_ << line;
}

void TumWriter::close() {
  for (std::ofstream* f : {&rgb_, &depth_, &groundtruth_, &accelerometer_, &gyro_}) {
    f->flush();
    if (!*f) throw InputError(dir_ + ": writing the recording lists failed");
    f->close();
  }
}

}  // namespace hq::sim
