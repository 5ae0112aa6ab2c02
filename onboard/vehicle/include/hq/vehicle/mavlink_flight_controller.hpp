#pragma once
/// The flight controller over MAVLink (PX4, ArduPilot, hq-sim --sitl): HIGHRES_IMU and ATTITUDE
/// in, SET_ATTITUDE_TARGET and the velocity (ODOMETRY, or VISION_SPEED_ESTIMATE by option) out,
/// arming and the offboard mode by COMMAND_LONG, health from HEARTBEAT, SYS_STATUS and
/// STATUSTEXT.
///
/// Clocks: the FC stamps in its boot time; the runtime clock is whatever t_ns poll() is given.
/// When the FC answers TIMESYNC (PX4 does; https://mavlink.io/en/services/timesync.html), the
/// offset comes from the round trips: we send tc1 = 0, ts1 = our time, the FC answers with its
/// time in tc1 and ts1 echoed, and offset = (ts1 + receipt) / 2 - tc1 assuming a symmetric
/// path; answers slower than timesync_max_rtt_s are dropped and the rest filtered. Until then,
/// or with an FC that never answers, offset = min over a sliding window of (t_ns at receipt -
/// FC stamp), because every packet arrives late by the transport delay and the least-delayed
/// one bounds it most tightly (the minimum-delay rule of one-way clock estimation). The offset
/// stamps what we send (time_boot_ms, usec) in the FC's clock.
///
/// With a GCS (`gcs`), the companion is also a MAVLink router between the FC and the GCS
/// (mavlink::Router; what mavlink-router or MAVROS's GCS bridge do elsewhere): the FC's frames
/// are forwarded as they arrive, tapped from the same parse, the GCS's frames go to the FC, and
/// our own broadcasts (heartbeat, the velocity as ODOMETRY or VISION_SPEED_ESTIMATE) reach the
/// GCS too, so it sees the companion as a component; what we address to the FC (setpoints,
/// commands, TIMESYNC once the FC is heard) does not. Only the FC's frames set the clock: a
/// GCS's TIMESYNC answers are never read as the FC's.

#include "hq/base/format_into.hpp"
#include "hq/config/strict_yaml.hpp"
#include "hq/mavlink/codec.hpp"
#include "hq/mavlink/router.hpp"
#include "hq/mavlink/transport.hpp"
#include "hq/vehicle/flight_controller.hpp"

#include <array>
#include <cstdint>
#include <cstdio>
#include <fmt/format.h>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

namespace hq::vehicle {

struct MavlinkFcConfig {
  enum class Autopilot { kAuto, kPx4, kArduPilot };
  /// ODOMETRY: what PX4's EKF2 reads external-vision velocity from (body FRD velocity, no
  /// pose). VISION_SPEED_ESTIMATE: NED velocity, for ArduPilot's VISO MAVLink backend, which
  /// takes ODOMETRY's pose as well and HaptiQuad has none to give.
  enum class VelocityMessage { kOdometry, kVisionSpeedEstimate };
  std::string transport = "udp:127.0.0.1:14540";  ///< mavlink::open_transport() spec.
  /// A ground control station the FC's traffic is routed to and from: "" none,
  /// udp:HOST:PORT (a GCS listening there, QGroundControl's default is 14550) or
  /// udp-listen:[HOST:]PORT (the GCS's address learnt from what it sends; all interfaces when
  /// HOST is omitted, since a GCS is on another machine).
  std::string gcs;
  std::uint8_t system_id = 1;       ///< Ours (a companion shares the vehicle's).
  std::uint8_t component_id = 191;  ///< MAV_COMP_ID_ONBOARD_COMPUTER.
  /// Nothing from the FC (heartbeat, IMU, attitude: any message) for longer: not connected.
  double heartbeat_timeout_s = 1.0;
  double heartbeat_rate_hz = 1.0;  ///< Our HEARTBEAT, sent from poll().
  /// Collective thrust at full throttle, to normalise SET_ATTITUDE_TARGET's thrust (the simulated
  /// vehicle's 4 rotors give 32.9 N).
  double max_thrust_n = 32.9;
  Autopilot autopilot = Autopilot::kAuto;  ///< kAuto: from the FC's HEARTBEAT.
  /// The commanded yaw never leads the FC's yaw by more than this (no wind-up while it lags).
  double max_yaw_lead_rad = 0.3;
  /// HIGHRES_IMU rate asked of the FC once it is heard (MAV_CMD_SET_MESSAGE_INTERVAL).
  double imu_rate_hz = 200.0;
  VelocityMessage velocity_message = VelocityMessage::kOdometry;
  double timesync_rate_hz = 10.0;    ///< TIMESYNC requests (as MAVSDK and mavros send); 0: none.
  double timesync_max_rtt_s = 0.01;  ///< Slower round trips say little of the offset: dropped.

  /// Throws hq::InputError naming the key after the prefix `where`, e.g.
  /// `config/onboard.yaml: mavlink.max_thrust_n = -1, expected > 0 and <= 10000`.
  void validate(const std::string& where = "mavlink.") const;
};

/// The GCS spec as the transport opens it: udp-listen:PORT listens on every interface.
std::string gcs_transport_spec(const std::string& gcs);

/// What the routing between the FC and a GCS did, for the run's summary.
struct GcsRouting {
  std::string spec;                     ///< As configured, e.g. udp:192.168.1.20:14550.
  std::string peer;                     ///< The GCS's address, "" if never heard (udp-listen).
  int gcs_system = -1;                  ///< The GCS's system id as heard, -1 never.
  std::uint64_t fc_to_gcs = 0;          ///< FC frames forwarded to the GCS.
  std::uint64_t gcs_to_fc = 0;          ///< GCS frames forwarded to the FC.
  std::uint64_t companion_to_gcs = 0;   ///< Our own broadcasts (heartbeat, ODOMETRY).
  std::uint64_t gcs_send_failures = 0;  ///< Not sent: no GCS address yet, or a socket error.
  std::uint64_t fc_send_failures = 0;   ///< GCS frames the FC's transport refused.
  mavlink::RouterCounters router;
  mavlink::ParserCounters gcs_parser;  ///< Frames from the GCS: bad CRC, truncated, ...
};

/// Reads the `mavlink:` section strictly: transport, gcs, system_id, component_id,
/// heartbeat_timeout_s, heartbeat_rate_hz, max_thrust_n, autopilot (auto | px4 | ardupilot),
/// max_yaw_lead_rad, imu_rate_hz, velocity_message (odometry | vision_speed_estimate),
/// timesync_rate_hz, timesync_max_rtt_s; then validate().
void read_config(config::StrictMap& section, MavlinkFcConfig& out);
/// "odometry" or "vision_speed_estimate" (config key, --fc-velocity-message); nullopt otherwise.
std::optional<MavlinkFcConfig::VelocityMessage> parse_velocity_message(std::string_view name);

class MavlinkFlightController final : public FlightController {
 public:
  /// Opens config.transport; throws hq::InputError on a bad config or transport spec.
  explicit MavlinkFlightController(const MavlinkFcConfig& config);
  /// Over a transport opened by the caller (tests, tools).
  MavlinkFlightController(const MavlinkFcConfig& config,
                          std::unique_ptr<mavlink::Transport> transport);
  MavlinkFlightController(const MavlinkFlightController&) = delete;
  MavlinkFlightController& operator=(const MavlinkFlightController&) = delete;

  void poll(std::int64_t t_ns, FcSink& sink) override;
  /// SET_ATTITUDE_TARGET, q = Rz(yaw_target) Ry(pitch) Rx(roll) of B (FRD) in NED. Not sent
  /// (counted a send failure) if not finite or no FC has been heard yet.
  void send_setpoint(std::int64_t t_ns, const control::AttitudeSetpoint& setpoint) override;
  /// ODOMETRY: v_B = R_H_B^T v_H (child frame MAV_FRAME_BODY_FRD), its covariance rotated
  /// likewise, pose unknown (NaN), estimator VIO, quality from the source and the covariance.
  /// Or VISION_SPEED_ESTIMATE: v_NED = Rz(fc_yaw) v_H. Not sent (a send failure) if not finite.
  void send_velocity(const VelocityReport& report) override;
  void request_arm_offboard(std::int64_t t_ns) override;
  void request_disarm(std::int64_t t_ns) override;
  [[nodiscard]] FcStatus status(std::int64_t t_ns) const override;
  [[nodiscard]] FcCounters counters() const override;
  [[nodiscard]] std::string describe() const override;
  /// The routing to and from the GCS; nullopt without one. Allocates (the addresses).
  [[nodiscard]] std::optional<GcsRouting> gcs_routing() const;

 private:
  /// Router links: our own frames, the FC's, the GCS's.
  static constexpr std::size_t kLinkCompanion = 0;
  static constexpr std::size_t kLinkFc = 1;
  static constexpr std::size_t kLinkGcs = 2;
  using Autopilot = MavlinkFcConfig::Autopilot;
  static constexpr std::size_t kOffsetWindow = 64;

  void handle(std::int64_t t_ns, const mavlink::FrameHeader& header,
              const mavlink::Message& message, FcSink& sink);
  void handle_heartbeat(std::int64_t t_ns, const mavlink::FrameHeader& header,
                        const mavlink::Heartbeat& hb);
  void update_clock(std::int64_t t_ns, std::int64_t fc_stamp_ns);
  void handle_timesync(std::int64_t t_ns, const mavlink::FrameHeader& header,
                       const mavlink::Timesync& timesync);
  /// The offset the stamps use: TIMESYNC's once it has converged, else the least-delayed one.
  [[nodiscard]] std::int64_t clock_offset_ns() const;
  [[nodiscard]] std::int64_t fc_time_ns(std::int64_t t_ns) const;
  [[nodiscard]] bool connected(std::int64_t t_ns) const;
  [[nodiscard]] Autopilot autopilot() const;
  bool send(const mavlink::Message& message);
  /// Sends one received frame to the links the router chose (not the companion: it has read it).
  void forward(std::size_t from, const mavlink::RawFrame& frame);
  /// Everything the GCS sent: routed to the FC; mode and arming commands said as events.
  void poll_gcs(FcSink& sink);
  void send_command(std::uint16_t command, float param1, float param2);
  /// Formats into text_ (no allocation) and hands it to the sink.
  template <typename... Args>
  void event(FcSink& sink, FcSeverity severity, fmt::format_string<Args...> format,
             Args&&... args) {
    emit(sink, severity,
         hq::format_into(text_.data(), text_.size(), format, std::forward<Args>(args)...).size());
  }
  void emit(FcSink& sink, FcSeverity severity, std::size_t length);

  MavlinkFcConfig config_;
  std::unique_ptr<mavlink::Transport> transport_;
  mavlink::Encoder encoder_;
  mavlink::Parser parser_;
  std::unique_ptr<mavlink::Transport> gcs_;  ///< Null without a GCS.
  mavlink::Parser gcs_parser_;
  mavlink::Router router_{3, kLinkCompanion};
  /// sent_[from][to]: frames routed and sent, by link.
  std::array<std::array<std::uint64_t, 3>, 3> sent_{};
  std::uint64_t gcs_send_failures_ = 0;
  std::uint64_t fc_forward_failures_ = 0;
  int gcs_system_ = -1;
  std::array<std::uint8_t, 65536> rx_{};
  std::array<std::uint8_t, mavlink::kMaxFrameSize> tx_{};
  std::array<char, 160> text_{};  ///< Event text, formatted without allocating.

  // The flight controller as last heard.
  bool have_target_ = false;
  std::uint8_t target_system_ = 0;
  std::uint8_t target_component_ = 0;
  Autopilot heard_autopilot_ = Autopilot::kAuto;
  std::int64_t last_heartbeat_ns_ = -1;
  std::int64_t last_heard_ns_ = -1;  ///< Any message from the FC.
  bool requested_streams_ = false;
  bool armed_ = false;
  bool offboard_ = false;
  double battery_v_ = -1.0;
  int battery_pct_ = -1;
  bool have_fc_yaw_ = false;
  double fc_yaw_rad_ = 0.0;

  // What we last said in events, so each change is said once.
  bool said_connected_ = false;
  bool said_armed_ = false;
  bool said_offboard_ = false;
  bool pending_no_autopilot_ = false;
  bool said_ardupilot_odometry_ = false;

  // Clock mapping: offsets (receipt - FC stamp) of the last kOffsetWindow IMU samples.
  std::array<std::int64_t, kOffsetWindow> offsets_ns_{};
  std::size_t offsets_count_ = 0;
  std::size_t offsets_next_ = 0;
  std::int64_t offset_ns_ = 0;
  bool have_offset_ = false;
  std::int64_t last_imu_t_ns_ = 0;
  bool have_imu_ = false;

  // TIMESYNC: the offset (runtime - FC) from round trips, filtered.
  std::int64_t last_timesync_sent_ns_ = -1;
  std::int64_t timesync_pending_ts1_ns_ = -1;  ///< Our last request's stamp, not yet answered.
  double timesync_offset_ns_ = 0.0;
  double timesync_variance_ns2_ = 0.0;
  int timesync_far_in_a_row_ = 0;

  // Commanded yaw, integrated from yaw_rate_radps while armed and offboard.
  double yaw_target_rad_ = 0.0;
  std::int64_t last_setpoint_ns_ = 0;
  bool yaw_integrating_ = false;

  bool sent_first_heartbeat_ = false;
  std::int64_t last_heartbeat_sent_ns_ = 0;
  FcCounters counters_;
};

}  // namespace hq::vehicle
