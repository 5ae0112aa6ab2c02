#include "hq/sim/tum_writer.hpp"

#include <sstream>

namespace hq::sim {

namespace {

sources::TumRecordingOptions sim_recording(const Eigen::Isometry3d& T_B_C) {
  sources::TumRecordingOptions options;
  options.description = "hq-sim";
  options.camera_name = "hq_sim";
  options.replace_existing = true;
  options.ground_truth = true;
  options.gyro = true;
  options.accel_note = " (specific force, body NED frame, m/s^2)";
  options.gyro_note = " (body NED frame, rad/s)";
  const Eigen::Quaterniond q(T_B_C.linear());
  const Eigen::Vector3d& p = T_B_C.translation();
  std::ostringstream mount;
  mount << "# T_B_C (body NED, camera optical): p_B_C_m and q_B_C xyzw\n"
        << "# p_B_C_m: [" << p.x() << ", " << p.y() << ", " << p.z() << "]\n"
        << "# q_B_C_xyzw: [" << q.x() << ", " << q.y() << ", " << q.z() << ", " << q.w() << "]\n";
  options.camera_comment = mount.str();
  return options;
}

}  // namespace

TumWriter::TumWriter(const std::string& dir, const geometry::PinholeCamera& camera,
                     const Eigen::Isometry3d& T_B_C)
    : recorder_(dir, camera, sim_recording(T_B_C)) {}

void TumWriter::write_frame(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m,
                            const Eigen::Isometry3d& T_N_C) {
  recorder_.write_frame(t_ns, image, depth_m);
  recorder_.write_ground_truth(t_ns, T_N_C);
}

void TumWriter::write_imu(const ImuSample& sample) {
  recorder_.write_accel(recording::AccelSample{sample.t_ns, sample.f_B_mps2});
  recorder_.write_gyro(sample.t_ns, sample.omega_B_radps);
}

}  // namespace hq::sim
