#pragma once
/// The frame vocabulary every component, IDL field, CSV/MCAP column and console label uses.
///
/// Frames (one letter each; the core paper's name in brackets where it differs):
///   C  camera, optical: x right, y down, z forward (OpenCV, TUM).
///   Ck the camera at frame k; C0 the camera when odometry started.
///   B  body, FRD: x forward, y right, z down [the core paper's Q].
///   H  horizontal: B with roll and pitch taken out; x forward and level, z down (core eq. 5).
///   O  odometry origin: the camera frame C0 in which the dense odometry integrates poses.
///   N  the level NWU world of the complementary filter and the simulator [the core paper's W].
///   W  the marker map: NED, anchored at the map's first marker (marker papers' world).
///   M  one marker's own frame (marker i: Mi).
///   L  the flight controller's local NED frame (MAVLink LOCAL_NED).
///   E  ROS world, ENU (REP-103/105 odom/map); F the ROS body, FLU (base_link).
///   G  the world an external ground truth is given in: a recording's groundtruth.txt (TUM: the
///      motion-capture frame), the odometry tests' rendered scene. S the sensor whose
///      ground-truth trajectory that is (TUM: the colour camera).
///
/// Quantities:
///   T_a_b  the rigid transform that maps points expressed in b into a: p_a = T_a_b * p_b,
///          so T_a_b * T_b_c == T_a_c, and T_a_b is also "the pose of b in a".
///   R_a_b  its rotation; p_a_b (or t_a_b) the origin of b expressed in a.
///   v_a_mps, omega_a_radps, a_a_mps2  a velocity, angular rate or acceleration expressed in a
///          (of the body unless the name says otherwise), e.g. v_H_mps, omega_B_radps.
///   p_a / p_a_m  a point expressed in a.
/// Names keep the unit suffix; a frame letter never stands for anything else, and a frame is
/// never spelt out as a word in a name (scripts/check-vocabulary; the few names where "body",
/// "world" or "horizontal" is not a frame are its allow-list).

namespace hq::geometry {}  // namespace hq::geometry
