#include "hq/sim/tum_writer.hpp"

#include <sstream>

namespace hq::sim {

namespace {

sources::TumRecordingOptions sim_recording(const Eigen::Isometry3d& T_body_camera) {
  sources::TumRecordingOptions options;
  options.description = "hq-sim";
  options.camera_name = "hq_sim";
  options.replace_existing = true;
  options.ground_truth = true;
  options.gyro = true;
  options.accel_note = " (specific force, body NED frame, m/s^2)";
  options.gyro_note = " (body NED frame, rad/s)";
  const Eigen::Quaterniond q(T_body_camera.linear());
  const Eigen::Vector3d& p = T_body_camera.translation();
  std::ostringstream mount;
  mount << "# T_body_camera (body NED, camera optical): p_body_camera_m and q_body_camera xyzw\n"
        << "# p_body_camera_m: [" << p.x() << ", " << p.y() << ", " << p.z() << "]\n"
        << "# q_body_camera_xyzw: [" << q.x() << ", " << q.y() << ", " << q.z() << ", " << q.w()
        << "]\n";
  options.camera_comment = mount.str();
  return options;
}

}  // namespace

TumWriter::TumWriter(const std::string& dir, const geometry::PinholeCamera& camera,
                     const Eigen::Isometry3d& T_body_camera)
    : recorder_(dir, camera, sim_recording(T_body_camera)) {}

void TumWriter::write_frame(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m,
                            const Eigen::Isometry3d& T_N_C) {
  recorder_.write_frame(t_ns, image, depth_m);
  recorder_.write_ground_truth(t_ns, T_N_C);
}

void TumWriter::write_imu(const ImuSample& sample) {
  recorder_.write_accel(recording::AccelSample{sample.t_ns, sample.f_body_mps2});
  recorder_.write_gyro(sample.t_ns, sample.omega_body_radps);
}

}  // namespace hq::sim
