#include "hq/mcap_recorder/flight_recorder.hpp"

#include "hq/flight_log/spsc_queue.hpp"

#include "ground_schemas.hpp"

#include <atomic>
#include <optional>

namespace hq::mcap_recorder {
namespace {

// What only the ground knows, one GroundSample per command tick, written as /ground/haptics and
// /ground/link on the link log's thread.
class GroundSource final : public flight_log::LocalSource {
 public:
  explicit GroundSource(std::size_t capacity) : queue_(capacity) {}

  void add_channels(flight_log::ChannelWriter& out) override {
    haptics_channel_ =
        out.add_json_channel("/ground/haptics", "hq_ground.Haptics", kHapticsSchema, {});
    link_channel_ = out.add_json_channel("/ground/link", "hq_ground.Link", kLinkSchema, {});
  }

  void drain(flight_log::ChannelWriter& out) override {
    queue_.drain([&](const GroundSample& g) {
      flight_log::Json& json = out.json();
      json.clear();
      json.raw("{\"timestamp\":");
      json.stamp(g.t_ns);
      json.raw(g.command_valid ? ",\"command_valid\":true" : ",\"command_valid\":false");
      json.raw(",\"v_cmd_H_mps\":");
      json.vector3(g.v_cmd_H_mps);
      json.raw(",\"yaw_rate_cmd_radps\":");
      json.number(g.yaw_rate_cmd_radps);
      json.raw(",\"p_D_m\":");
      json.vector3(g.p_D_m);
      json.raw(",\"F_D_n\":");
      json.vector3(g.F_D_n);
      json.raw("}");
      out.write_json(haptics_channel_, g.t_ns, g.t_ns);
      json.clear();
      json.raw("{\"timestamp\":");
      json.stamp(g.t_ns);
      json.raw(",\"latency_ms\":");
      json.number(g.latency_ms);
      json.raw(",\"round_trip_ms\":");
      json.number(g.round_trip_ms);
      json.raw(",\"state_age_ms\":");
      json.number(g.state_age_ms);
      json.raw("}");
      out.write_json(link_channel_, g.t_ns, g.t_ns);
    });
  }

  [[nodiscard]] std::uint64_t dropped() const override { return queue_.dropped(); }
  [[nodiscard]] const char* dropped_key() const override { return "ground_samples_dropped"; }

  bool push(const GroundSample& sample) noexcept { return queue_.push(sample); }

 private:
  flight_log::SpscQueue<GroundSample> queue_;
  std::uint16_t haptics_channel_ = 0;
  std::uint16_t link_channel_ = 0;
};

flight_log::LinkLogOptions link_log_options(const FlightRecorderOptions& options) {
  flight_log::LinkLogOptions o;
  o.path = options.path;
  o.link = options.link;
  // The station's own identity when the link is secured (its permissions let it read every
  // link topic of its vehicles); plain DDS otherwise.
  o.role = security::Role::kStation;
  o.attachments = options.attachments;
  o.writer = options.writer;
  o.camera_mount = options.camera_mount;
  return o;
}

}  // namespace

struct FlightRecorder::Impl {
  explicit Impl(const FlightRecorderOptions& options)
      : ground(options.ground_queue_capacity), log(link_log_options(options), &ground) {}

  GroundSource ground;
  flight_log::LinkLog log;
  std::atomic<bool> closed{false};
  RecorderReport report;
};

FlightRecorder::FlightRecorder(const FlightRecorderOptions& options)
    : impl_(std::make_unique<Impl>(options)) {}

FlightRecorder::~FlightRecorder() {
  try {
    close();
  } catch (...) {
    // close() reports through its return value; nothing may escape a destructor.
  }
}

bool FlightRecorder::failed() const noexcept { return impl_->log.failed(); }

const std::string& FlightRecorder::error() const noexcept { return impl_->log.error(); }

const std::vector<std::string>& FlightRecorder::attachments_skipped() const {
  return impl_->log.attachments_skipped();
}

bool FlightRecorder::push(const GroundSample& sample) noexcept {
  if (impl_->closed.load(std::memory_order_relaxed)) return false;
  return impl_->ground.push(sample);
}

const RecorderReport& FlightRecorder::close(const mcap::KeyValues& summary) {
  Impl& d = *impl_;
  if (d.closed.exchange(true)) return d.report;
  static_cast<flight_log::RecorderReport&>(d.report) = d.log.close(summary);
  d.report.ground_samples_dropped = d.report.local_samples_dropped;
  return d.report;
}

}  // namespace hq::mcap_recorder
