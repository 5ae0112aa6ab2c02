#include "hq/geometry/ros_frames.hpp"

namespace hq::geometry {

Eigen::Vector3d enu_from_ned(const Eigen::Vector3d& v_ned) {
  return {v_ned.y(), v_ned.x(), -v_ned.z()};
}

Eigen::Vector3d flu_from_frd(const Eigen::Vector3d& v_frd) {
  return {v_frd.x(), -v_frd.y(), -v_frd.z()};
}

Eigen::Matrix3d R_ned_B(double roll_rad, double pitch_rad, double yaw_rad) {
  return (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Quaterniond q_E_F(double roll_rad, double pitch_rad, double yaw_rad) {
  Eigen::Matrix3d R_E_ned;
  R_E_ned << 0, 1, 0,  //
      1, 0, 0,         //
      0, 0, -1;
  const Eigen::Matrix3d R_B_F = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  const Eigen::Matrix3d R_E_F = R_E_ned * R_ned_B(roll_rad, pitch_rad, yaw_rad) * R_B_F;
  return Eigen::Quaterniond(R_E_F).normalized();
}

Eigen::Vector3d v_F_from_v_H(const Eigen::Vector3d& v_H_mps, double roll_rad, double pitch_rad) {
  // H is B with roll and pitch taken out: R_H_B = R_ned_B(roll, pitch, 0).
  const Eigen::Vector3d v_B_mps = R_ned_B(roll_rad, pitch_rad, 0.0).transpose() * v_H_mps;
  return flu_from_frd(v_B_mps);
}

HorizontalCommand command_from_twist(const Eigen::Vector3d& linear_F_mps,
                                     double angular_z_F_radps) {
  // FLU and FRD share x; y and z flip, and so does the rate about z.
  return {flu_from_frd(linear_F_mps), -angular_z_F_radps};
}

RosCameraFrames ros_camera_frames(const CameraMount& mount) {
  // Columns: the optical x (right), y (down), z (forward) in camera_link (forward, left, up).
  Eigen::Matrix3d R_link_optical;
  R_link_optical << 0, 0, 1,  //
      -1, 0, 0,               //
      0, -1, 0;
  const Eigen::Matrix3d R_F_B = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  const Eigen::Matrix3d R_F_optical = R_F_B * mount.R_B_C();
  RosCameraFrames frames;
  frames.T_F_camera_link.linear() = R_F_optical * R_link_optical.transpose();
  frames.T_F_camera_link.translation() = flu_from_frd(mount.p_B_C_m());
  frames.T_camera_link_optical.linear() = R_link_optical;
  return frames;
}

}  // namespace hq::geometry
