#include "hq/onboard_log/onboard_recorder.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"
#include "hq/base/log.hpp"
#include "hq/flight_log/spsc_queue.hpp"

#include "onboard_schemas.hpp"
#include "ros2_record.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fmt/format.h>
#include <limits>
#include <system_error>

namespace hq::onboard_log {
namespace {

// One chain step as the channels write it: plain values and static texts, copied into a queue
// slot on the frame path.
struct StepSample {
  std::int64_t t_ns = 0;
  bool frame = false;
  const char* tracking = "";
  const char* tracking_reason = "";
  double valid_ratio = 0.0;
  double v_C_raw_mps[3] = {0, 0, 0};
  double v_C_mps[3] = {0, 0, 0};
  const char* estimate_status = "";
  const char* estimate_reason = "";
  double v_B_mps[3] = {0, 0, 0};
  double v_H_mps[3] = {0, 0, 0};
  double omega_B_radps[3] = {0, 0, 0};
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  const char* mode = "";
  const char* flight_state = "";
  double v_des_H_mps[3] = {0, 0, 0};
  double v_obs_H_mps[3] = {0, 0, 0};
  control::AttitudeSetpoint setpoint;
  bool safe_hover = false;
  const char* safe_hover_reason = "";
  bool streaming = false;  ///< The setpoint went to the flight controller.
  bool fc_lost = false;
  double height_m = 0.0;
  double clearance_m = -1.0;
  pipeline::StageDurations durations;
};

// One IMU sample as a queue slot holds it (Eigen vectors are not trivially copyable).
struct ImuRecord {
  std::int64_t t_ns = 0;
  double omega_B_radps[3] = {0, 0, 0};
  double f_B_mps2[3] = {0, 0, 0};
};

void copy3(const Eigen::Vector3d& v, double out[3]) {
  out[0] = v.x();
  out[1] = v.y();
  out[2] = v.z();
}

// The one place that reads the chain's output fields.
StepSample make_step(const pipeline::ChainOutput& out, const vehicle::VehicleStatus& status) {
  StepSample s;
  const estimator::VelocityEstimate& e = out.estimate;
  s.t_ns = out.t_ns;
  s.frame = out.frame;
  s.tracking = out.frame ? odometry::to_string(out.tracking) : "none";
  s.tracking_reason = out.tracking_reason != nullptr ? out.tracking_reason : "";
  s.valid_ratio = out.valid_ratio;
  copy3(e.v_C_raw_mps, s.v_C_raw_mps);
  copy3(e.v_C_mps, s.v_C_mps);
  s.estimate_status = estimator::to_string(e.status);
  s.estimate_reason = e.reason != nullptr ? e.reason : "";
  copy3(e.v_B_mps, s.v_B_mps);
  copy3(e.v_H_mps, s.v_H_mps);
  copy3(e.omega_B_radps, s.omega_B_radps);
  s.roll_rad = e.roll_rad;
  s.pitch_rad = e.pitch_rad;
  s.mode = modes::to_string(out.mode.mode);
  s.flight_state = modes::to_string(out.flight_state);
  copy3(out.mode.v_des_H_mps, s.v_des_H_mps);
  copy3(out.obstacles.v_obs_H_mps, s.v_obs_H_mps);
  s.setpoint = out.mode.control.setpoint;
  s.safe_hover = out.safe_hover;
  s.safe_hover_reason = out.safe_hover_reason != nullptr ? out.safe_hover_reason : "";
  s.streaming = status.streaming;
  s.fc_lost = status.fc_lost;
  s.height_m = out.height_m;
  s.clearance_m = out.clearance_m;
  s.durations = out.durations;
  return s;
}

// What only the vehicle knows, drained on the link log's thread.
class OnboardSource final : public flight_log::LocalSource {
 public:
  OnboardSource(std::size_t steps, std::size_t imu, Ros2Record* ros2)
      : steps_(steps), imu_(imu), ros2_(ros2) {}

  // The ROS 2 bag is derived from the link's samples, on this thread.
  void on_link_state(const link::VehicleState& state, std::int64_t log_ns,
                     std::int64_t publish_ns) override {
    if (ros2_ != nullptr) ros2_->on_state(state, log_ns, publish_ns);
  }
  void on_link_camera(const link::CameraFrame& frame, std::int64_t log_ns,
                      std::int64_t publish_ns) override {
    if (ros2_ != nullptr) ros2_->on_camera(frame, log_ns, publish_ns);
  }

  void add_channels(flight_log::ChannelWriter& out) override {
    imu_channel_ = out.add_json_channel("/onboard/imu", "hq_onboard.Imu", kImuSchema,
                                        {{"frame", "B (FRD body)"}});
    odometry_channel_ = out.add_json_channel("/onboard/odometry", "hq_onboard.Odometry",
                                             kOdometrySchema, {{"frame", "C (camera optical)"}});
    estimator_channel_ =
        out.add_json_channel("/onboard/estimator", "hq_onboard.Estimator", kEstimatorSchema, {});
    control_channel_ =
        out.add_json_channel("/onboard/control", "hq_onboard.Control", kControlSchema, {});
    timing_channel_ =
        out.add_json_channel("/onboard/timing", "hq_onboard.Timing", kTimingSchema, {});
  }

  void drain(flight_log::ChannelWriter& out) override {
    // Set before the first sample was queued (the queue's release orders it).
    const std::int64_t offset_ns = epoch_offset_ns_.load(std::memory_order_acquire);
    const std::int64_t now_ns = wall_ns();
    imu_.drain([&](const ImuRecord& m) {
      const std::int64_t log_ns = m.t_ns + offset_ns;
      note_lag(now_ns - log_ns);
      flight_log::Json& j = begin(out, log_ns, m.t_ns);
      j.raw(",\"omega_B_radps\":");
      j.vector3(m.omega_B_radps);
      j.raw(",\"f_B_mps2\":");
      j.vector3(m.f_B_mps2);
      j.raw("}");
      out.write_json(imu_channel_, log_ns, log_ns);
    });
    steps_.drain([&](const StepSample& s) {
      note_lag(now_ns - (s.t_ns + offset_ns));
      write_step(out, s, s.t_ns + offset_ns);
    });
    if (ros2_ != nullptr) {
      ros2_->tick(std::chrono::duration_cast<std::chrono::nanoseconds>(
                      std::chrono::steady_clock::now().time_since_epoch())
                      .count());
    }
  }

  void describe_clock(mcap::KeyValues& metadata) const override {
    const std::int64_t offset_ns = epoch_offset_ns_.load(std::memory_order_acquire);
    if (offset_ns == kNoOffset) return;
    metadata["chain_clock"] =
        "the on-board chain's t_ns (simulated time, or the monotonic clock on a vehicle), in "
        "each /onboard/ message as t_ns; log_time = t_ns + chain_to_epoch_offset_ns";
    metadata["chain_to_epoch_offset_ns"] = std::to_string(offset_ns);
    // How far the mapped stamps were behind (or, negative, ahead of) the clock when drained:
    // the queues' delay, plus the drift of a simulated clock from the wall clock.
    metadata["chain_lag_min_ns"] = std::to_string(lag_min_ns_);
    metadata["chain_lag_max_ns"] = std::to_string(lag_max_ns_);
  }

  [[nodiscard]] std::uint64_t dropped() const override { return steps_.dropped() + imu_.dropped(); }
  [[nodiscard]] const char* dropped_key() const override { return "onboard_samples_dropped"; }

  void push_step(const StepSample& s) noexcept {
    steps_pushed_.fetch_add(1, std::memory_order_relaxed);
    map_clock(s.t_ns);
    steps_.push(s);
  }
  void push_imu(const vehicle::FcImuSample& m) noexcept {
    imu_pushed_.fetch_add(1, std::memory_order_relaxed);
    map_clock(m.t_ns);
    ImuRecord r;
    r.t_ns = m.t_ns;
    copy3(m.omega_B_radps, r.omega_B_radps);
    copy3(m.f_B_mps2, r.f_B_mps2);
    imu_.push(r);
  }
  std::uint64_t steps_pushed() const { return steps_pushed_.load(std::memory_order_relaxed); }
  std::uint64_t imu_pushed() const { return imu_pushed_.load(std::memory_order_relaxed); }

 private:
  void note_lag(std::int64_t lag_ns) {
    lag_min_ns_ = std::min(lag_min_ns_, lag_ns);
    lag_max_ns_ = std::max(lag_max_ns_, lag_ns);
  }

  static std::int64_t wall_ns() noexcept {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(
               std::chrono::system_clock::now().time_since_epoch())
        .count();
  }

  // One offset per run, from the first sample: the chain's clock (simulated, or monotonic) to
  // the epoch the link samples are stamped in. Simulated time maps to the wall clock at the
  // run's first step; hq-sim-flight paces it in real time, so the two stay together
  // (chain_lag_max_ns in the metadata says how well).
  void map_clock(std::int64_t t_ns) noexcept {
    if (epoch_offset_ns_.load(std::memory_order_relaxed) != kNoOffset) return;
    std::int64_t expected = kNoOffset;
    epoch_offset_ns_.compare_exchange_strong(expected, wall_ns() - t_ns, std::memory_order_acq_rel);
  }

  // "timestamp" is the log time (epoch), so Foxglove plots these beside the link's channels;
  // "t_ns" the chain's own stamp, as the chain's logs and CSV files carry it.
  static flight_log::Json& begin(flight_log::ChannelWriter& out, std::int64_t log_ns,
                                 std::int64_t t_ns) {
    flight_log::Json& j = out.json();
    j.clear();
    j.raw("{\"timestamp\":");
    j.stamp(log_ns);
    j.raw(",\"t_ns\":");
    j.integer(t_ns);
    return j;
  }

  void write_step(flight_log::ChannelWriter& out, const StepSample& s, std::int64_t log_ns) {
    if (s.frame) {
      flight_log::Json& j = begin(out, log_ns, s.t_ns);
      j.raw(",\"tracking\":");
      j.string(s.tracking);
      j.raw(",\"reason\":");
      j.string(s.tracking_reason);
      j.raw(",\"valid_ratio\":");
      j.number(s.valid_ratio);
      j.raw(",\"v_C_raw_mps\":");
      j.vector3(s.v_C_raw_mps);
      j.raw(",\"v_C_mps\":");
      j.vector3(s.v_C_mps);
      j.raw("}");
      out.write_json(odometry_channel_, log_ns, log_ns);
    }
    {
      flight_log::Json& j = begin(out, log_ns, s.t_ns);
      j.raw(s.frame ? ",\"frame\":true,\"status\":" : ",\"frame\":false,\"status\":");
      j.string(s.estimate_status);
      j.raw(",\"reason\":");
      j.string(s.estimate_reason);
      j.raw(",\"v_B_mps\":");
      j.vector3(s.v_B_mps);
      j.raw(",\"v_H_mps\":");
      j.vector3(s.v_H_mps);
      j.raw(",\"omega_B_radps\":");
      j.vector3(s.omega_B_radps);
      j.raw(",\"roll_rad\":");
      j.number(s.roll_rad);
      j.raw(",\"pitch_rad\":");
      j.number(s.pitch_rad);
      j.raw("}");
      out.write_json(estimator_channel_, log_ns, log_ns);
    }
    {
      flight_log::Json& j = begin(out, log_ns, s.t_ns);
      j.raw(",\"mode\":");
      j.string(s.mode);
      j.raw(",\"flight_state\":");
      j.string(s.flight_state);
      j.raw(",\"v_des_H_mps\":");
      j.vector3(s.v_des_H_mps);
      j.raw(",\"v_obs_H_mps\":");
      j.vector3(s.v_obs_H_mps);
      j.raw(",\"thrust_n\":");
      j.number(s.setpoint.thrust_n);
      j.raw(",\"roll_rad\":");
      j.number(s.setpoint.roll_rad);
      j.raw(",\"pitch_rad\":");
      j.number(s.setpoint.pitch_rad);
      j.raw(",\"yaw_rate_radps\":");
      j.number(s.setpoint.yaw_rate_radps);
      j.raw(s.safe_hover ? ",\"safe_hover\":true" : ",\"safe_hover\":false");
      j.raw(",\"safe_hover_reason\":");
      j.string(s.safe_hover_reason);
      j.raw(s.streaming ? ",\"sent_to_fc\":true" : ",\"sent_to_fc\":false");
      j.raw(s.fc_lost ? ",\"fc_lost\":true" : ",\"fc_lost\":false");
      j.raw(",\"height_m\":");
      j.number(s.height_m);
      j.raw(",\"clearance_m\":");
      j.number(s.clearance_m);
      j.raw("}");
      out.write_json(control_channel_, log_ns, log_ns);
    }
    if (s.frame) {
      flight_log::Json& j = begin(out, log_ns, s.t_ns);
      for (int i = 0; i < pipeline::kStageCount; ++i) {
        j.raw(",\"");
        j.raw(pipeline::kStageNames[i]);
        j.raw("_ns\":");
        j.integer(pipeline::stage_ns(s.durations, i));
      }
      j.raw("}");
      out.write_json(timing_channel_, log_ns, log_ns);
    }
  }

  flight_log::SpscQueue<StepSample> steps_;
  flight_log::SpscQueue<ImuRecord> imu_;
  std::atomic<std::uint64_t> steps_pushed_{0};
  std::atomic<std::uint64_t> imu_pushed_{0};
  static constexpr std::int64_t kNoOffset = std::numeric_limits<std::int64_t>::min();
  std::atomic<std::int64_t> epoch_offset_ns_{kNoOffset};
  std::int64_t lag_min_ns_ = std::numeric_limits<std::int64_t>::max();  ///< log thread only
  std::int64_t lag_max_ns_ = std::numeric_limits<std::int64_t>::min();
  std::uint16_t imu_channel_ = 0;
  std::uint16_t odometry_channel_ = 0;
  std::uint16_t estimator_channel_ = 0;
  std::uint16_t control_channel_ = 0;
  std::uint16_t timing_channel_ = 0;
  Ros2Record* ros2_;  ///< Not owned; null when ros2.mcap is not recorded.
};

// The folder is made here, so an unwritable one is named before any DDS setup.
flight_log::LinkLogOptions link_log_options(const OnboardRecorderOptions& options) {
  if (options.dir.empty()) throw InputError("--record: expected a folder, got an empty name");
  std::error_code ec;
  std::filesystem::create_directories(options.dir, ec);
  if (ec) {
    throw InputError("--record " + options.dir + ": cannot create the folder: " + ec.message());
  }
  flight_log::LinkLogOptions o;
  o.path = (std::filesystem::path(options.dir) / kOnboardFileName).string();
  o.link = options.link;
  // The vehicle's own identity when the link is secured: its permissions let it read what it
  // publishes and what its stations send it.
  o.role = security::Role::kVehicle;
  o.attachments = options.attachments;
  o.writer = options.writer;
  o.record_link = options.record_link;
  o.camera_mount = options.camera_mount;
  return o;
}

// DIR/ros2.mcap when the link is recorded and link.ros2.record asks for it.
std::unique_ptr<Ros2Record> make_ros2_record(const OnboardRecorderOptions& options,
                                             const flight_log::LinkLogOptions& log_options) {
  if (!options.record_link || !options.link.ros2.record) return nullptr;
  // The link log refuses an existing onboard.mcap right after: leave no new file behind then.
  if (std::filesystem::exists(log_options.path)) return nullptr;
  Ros2RecordOptions o;
  o.path = (std::filesystem::path(options.dir) / kRos2FileName).string();
  o.ros_namespace = link::ros2_namespace(options.link);
  o.camera_mount = options.camera_mount;
  o.writer = log_options.writer;
  return std::make_unique<Ros2Record>(o);
}

}  // namespace

struct OnboardRecorder::Impl {
  explicit Impl(const OnboardRecorderOptions& options)
      : log_options(link_log_options(options)),
        ros2(make_ros2_record(options, log_options)),
        source(options.step_queue_capacity, options.imu_queue_capacity, ros2.get()),
        log(log_options, &source) {}
  std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  flight_log::LinkLogOptions log_options;
  std::unique_ptr<Ros2Record> ros2;  ///< Before the source and log, which use it.
  Ros2RecordReport ros2_report;
  OnboardSource source;
  flight_log::LinkLog log;
  std::atomic<bool> closed{false};
};

OnboardRecorder::OnboardRecorder(const OnboardRecorderOptions& options)
    : impl_(std::make_unique<Impl>(options)) {}

OnboardRecorder::~OnboardRecorder() {
  try {
    close();
  } catch (...) {
    // close() reports through its return value; nothing may escape a destructor.
  }
}

void OnboardRecorder::push_step(const pipeline::ChainOutput& out,
                                const vehicle::VehicleStatus& status) noexcept {
  if (impl_->closed.load(std::memory_order_relaxed)) return;
  impl_->source.push_step(make_step(out, status));
}

void OnboardRecorder::push_imu(const vehicle::FcImuSample& sample) noexcept {
  if (impl_->closed.load(std::memory_order_relaxed)) return;
  impl_->source.push_imu(sample);
}

void OnboardRecorder::set_camera(const geometry::PinholeCamera& camera) {
  impl_->log.set_camera(camera);
  if (impl_->ros2) impl_->ros2->set_camera(camera);
}

void OnboardRecorder::set_ros_clock(const ros2_bridge::RosClock& clock) {
  if (impl_->ros2) impl_->ros2->set_clock(clock);
}

const Ros2RecordReport& OnboardRecorder::ros2_report() const noexcept { return impl_->ros2_report; }

bool OnboardRecorder::failed() const noexcept { return impl_->log.failed(); }
const std::string& OnboardRecorder::error() const noexcept { return impl_->log.error(); }
const std::string& OnboardRecorder::path() const noexcept { return impl_->log_options.path; }
const std::vector<std::string>& OnboardRecorder::attachments_skipped() const {
  return impl_->log.attachments_skipped();
}
std::uint64_t OnboardRecorder::steps_pushed() const noexcept {
  return impl_->source.steps_pushed();
}
std::uint64_t OnboardRecorder::imu_pushed() const noexcept { return impl_->source.imu_pushed(); }
double OnboardRecorder::seconds_since_start() const noexcept {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - impl_->started).count();
}

const flight_log::RecorderReport& OnboardRecorder::close(const mcap::KeyValues& summary) {
  impl_->closed.store(true, std::memory_order_relaxed);
  const flight_log::RecorderReport& report = impl_->log.close(summary);
  // After the log's thread stopped: nothing writes to it any more.
  if (impl_->ros2) impl_->ros2_report = impl_->ros2->close();
  return report;
}

modes::OperatorCommand RecordingPort::poll(std::int64_t t_ns,
                                           std::vector<pipeline::ModeRequest>& requests) {
  return inner_ != nullptr ? inner_->poll(t_ns, requests) : modes::OperatorCommand{};
}

void RecordingPort::on_mode_result(std::int64_t t_ns, const pipeline::ModeRequest& request,
                                   const modes::ModeSwitch& result) {
  if (inner_ != nullptr) inner_->on_mode_result(t_ns, request, result);
}

void RecordingPort::on_output(const pipeline::ChainOutput& out,
                              const vehicle::VehicleStatus& status) {
  recorder_.push_step(out, status);
  if (inner_ != nullptr) inner_->on_output(out, status);
  if (!failure_told_ && recorder_.failed()) {
    failure_told_ = true;
    // Once per flight, so the text may be formatted here; the flight itself goes on.
    char text[512];
    hq::format_into(text, "on-board record stopped (flying on): {}", recorder_.error());
    on_event(out.t_ns, vehicle::FcSeverity::kError, text);
  }
}

void RecordingPort::on_frame(const sources::RgbdFrame& frame) {
  if (inner_ != nullptr) inner_->on_frame(frame);
}

void RecordingPort::on_event(std::int64_t t_ns, vehicle::FcSeverity severity,
                             std::string_view text) {
  if (inner_ != nullptr) {
    inner_->on_event(t_ns, severity, text);
  } else {
    switch (severity) {
      case vehicle::FcSeverity::kError:
        hq::log::error("hq-onboard: {}\n", text);
        break;
      case vehicle::FcSeverity::kWarning:
        hq::log::warn("hq-onboard: {}\n", text);
        break;
      case vehicle::FcSeverity::kInfo:
        hq::log::note("hq-onboard: {}\n", text);
        break;
    }
  }
}

namespace {
// Forwards everything the FC sends, pushing IMU samples to the recorder on the way.
class ImuTap final : public vehicle::FcSink {
 public:
  ImuTap(vehicle::FcSink& sink, OnboardRecorder& recorder) : sink_(sink), recorder_(recorder) {}
  void on_imu(const vehicle::FcImuSample& sample) override {
    recorder_.push_imu(sample);
    sink_.on_imu(sample);
  }
  void on_attitude(const vehicle::FcAttitude& attitude) override { sink_.on_attitude(attitude); }
  void on_fc_event(vehicle::FcSeverity severity, std::string_view text) override {
    sink_.on_fc_event(severity, text);
  }

 private:
  vehicle::FcSink& sink_;
  OnboardRecorder& recorder_;
};
}  // namespace

void RecordingFlightController::poll(std::int64_t t_ns, vehicle::FcSink& sink) {
  ImuTap tap(sink, recorder_);
  inner_.poll(t_ns, tap);
}

void print_report(std::FILE* out, const Ros2RecordReport& r) {
  if (r.path.empty()) return;
  fmt::print(out, "  {:<40} {}, {} messages, {} bytes\n", "ROS 2 record", r.path, r.messages,
             r.bytes);
  for (const auto& [topic, messages] : r.per_topic) {
    fmt::print(out, "  ros2 record {:<28} {} messages\n", topic, messages);
  }
  if (r.too_large > 0 || r.log_times_raised > 0) {
    fmt::print(out, "  {:<40} {} too large, {} log times raised\n", "ROS 2 record messages",
               r.too_large, r.log_times_raised);
  }
  if (!r.error.empty()) fmt::print(out, "  ROS 2 record FAILED: {}\n", r.error);
}

void print_report(std::FILE* out, const flight_log::RecorderReport& r) {
  fmt::print(out, "  {:<40} {}, {} messages, {} bytes, {} attachments\n", "on-board record", r.path,
             r.messages, r.bytes, r.attachments);
  for (const flight_log::ChannelReport& c : r.per_channel) {
    fmt::print(out, "  record {:<33} {} messages\n", c.topic, c.messages);
  }
  fmt::print(out, "  {:<40} {} dropped (queue full), {} not written\n", "on-board record samples",
             r.local_samples_dropped, r.samples_not_written);
  for (const std::string& s : r.attachments_skipped) {
    fmt::print(out, "  on-board record attachment skipped: {}\n", s);
  }
  if (!r.error.empty()) fmt::print(out, "  on-board record FAILED: {}\n", r.error);
}

}  // namespace hq::onboard_log
