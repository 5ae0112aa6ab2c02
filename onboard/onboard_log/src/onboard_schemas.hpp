#pragma once
/// JSON Schemas of the vehicle's own channels. Vectors are {x, y, z} in the frame their name
/// carries (B body FRD, H horizontal, C camera optical); SI units as named.

namespace hq::onboard_log {

#define HQ_ONBOARD_VEC3                                                 \
  R"j({"type":"object","properties":{"x":{"type":["number","null"]},)j" \
  R"j("y":{"type":["number","null"]},"z":{"type":["number","null"]}}})j"
#define HQ_ONBOARD_STAMP                                          \
  R"j({"type":"object","properties":{"sec":{"type":"integer"},)j" \
  R"j("nsec":{"type":"integer"}}})j"
// The chain's own stamp (simulated or monotonic ns); timestamp is the log time (epoch).
#define HQ_ONBOARD_CHAIN_STAMP R"j(,"t_ns":{"type":"integer"})j"
#define HQ_ONBOARD_NUMBER R"j({"type":["number","null"]})j"

inline constexpr const char* kImuSchema =
    R"j({"title":"hq_onboard.Imu","description":"One IMU sample from the flight controller: )j"
    R"j(gyro and specific force in B (FRD body)","type":"object","properties":{"timestamp":)j" HQ_ONBOARD_STAMP
        HQ_ONBOARD_CHAIN_STAMP R"j(,"omega_B_radps":)j" HQ_ONBOARD_VEC3
    R"j(,"f_B_mps2":)j" HQ_ONBOARD_VEC3 R"j(}})j";

inline constexpr const char* kOdometrySchema =
    R"j({"title":"hq_onboard.Odometry","description":"Dense odometry on one frame and the )j"
    R"j(camera velocity (core paper eq. 1 raw, eq. 2 filtered) in C","type":"object",)j"
    R"j("properties":{"timestamp":)j" HQ_ONBOARD_STAMP HQ_ONBOARD_CHAIN_STAMP
    R"j(,"tracking":{"type":"string"},"reason":{"type":"string"},"valid_ratio":)j" HQ_ONBOARD_NUMBER
    R"j(,"v_C_raw_mps":)j" HQ_ONBOARD_VEC3 R"j(,"v_C_mps":)j" HQ_ONBOARD_VEC3 R"j(}})j";

inline constexpr const char* kEstimatorSchema =
    R"j({"title":"hq_onboard.Estimator","description":"The velocity estimate at one step: )j"
    R"j(v_B (eq. 4), v_H (eq. 5), body rate, roll and pitch of the complementary filter",)j"
    R"j("type":"object","properties":{"timestamp":)j" HQ_ONBOARD_STAMP HQ_ONBOARD_CHAIN_STAMP
    R"j(,"frame":{"type":"boolean"},"status":{"type":"string"},"reason":{"type":"string"},)j"
    R"j("v_B_mps":)j" HQ_ONBOARD_VEC3 R"j(,"v_H_mps":)j" HQ_ONBOARD_VEC3
    R"j(,"omega_B_radps":)j" HQ_ONBOARD_VEC3 R"j(,"roll_rad":)j" HQ_ONBOARD_NUMBER
    R"j(,"pitch_rad":)j" HQ_ONBOARD_NUMBER R"j(}})j";

inline constexpr const char* kControlSchema =
    R"j({"title":"hq_onboard.Control","description":"Mode controller and velocity PID at one )j"
    R"j(step: v_des = v*_des + v_obs in H, the thrust/attitude setpoint and whether it was sent )j"
    R"j(to the flight controller","type":"object","properties":{"timestamp":)j" HQ_ONBOARD_STAMP
        HQ_ONBOARD_CHAIN_STAMP
    R"j(,"mode":{"type":"string"},"flight_state":{"type":"string"},"v_des_H_mps":)j" HQ_ONBOARD_VEC3
    R"j(,"v_obs_H_mps":)j" HQ_ONBOARD_VEC3 R"j(,"thrust_n":)j" HQ_ONBOARD_NUMBER
    R"j(,"roll_rad":)j" HQ_ONBOARD_NUMBER R"j(,"pitch_rad":)j" HQ_ONBOARD_NUMBER
    R"j(,"yaw_rate_radps":)j" HQ_ONBOARD_NUMBER
    R"j(,"safe_hover":{"type":"boolean"},"safe_hover_reason":{"type":"string"},)j"
    R"j("sent_to_fc":{"type":"boolean"},"fc_lost":{"type":"boolean"},"height_m":)j" HQ_ONBOARD_NUMBER
    R"j(,"clearance_m":)j" HQ_ONBOARD_NUMBER R"j(}})j";

inline constexpr const char* kTimingSchema =
    R"j({"title":"hq_onboard.Timing","description":"Wall time of each chain stage on one )j"
    R"j(frame (ns)","type":"object","properties":{"timestamp":)j" HQ_ONBOARD_STAMP
        HQ_ONBOARD_CHAIN_STAMP
    R"j(,"odometry_ns":{"type":"integer"},"estimator_ns":{"type":"integer"},)j"
    R"j("memory_ns":{"type":"integer"},"obstacles_ns":{"type":"integer"},)j"
    R"j("control_ns":{"type":"integer"},"total_ns":{"type":"integer"}}})j";

#undef HQ_ONBOARD_VEC3
#undef HQ_ONBOARD_STAMP
#undef HQ_ONBOARD_NUMBER
#undef HQ_ONBOARD_CHAIN_STAMP

}  // namespace hq::onboard_log
