// --record DIR (hq-onboard, hq-sim-flight): the on-board MCAP flight log (onboard/onboard_log), set
// up and closed here so each run mode adds a few lines only.

#include "hq/base/log.hpp"
#include "hq/config/data_path.hpp"
#include "hq/link/config.hpp"

#include "onboard_runs.hpp"

#include <csignal>
#include <cstdio>
#include <fmt/format.h>
#include <string>

namespace hq::onboard_app {

std::unique_ptr<onboard_log::OnboardRecorder> make_recorder(const Options& o,
                                                            const VehicleConfig& vehicle) {
  if (o.record_dir.empty()) return nullptr;
  // A file-size limit (ulimit -f) then fails the write with EFBIG, which the log reports as it
  // does a full disk, instead of SIGXFSZ killing the flight.
  std::signal(SIGXFSZ, SIG_IGN);
  onboard_log::OnboardRecorderOptions options;
  options.dir = o.record_dir;
  options.camera_mount = vehicle.camera;
  options.link =
      o.link_config_path.empty() ? link::LinkConfig{} : link::load_link_config(o.link_config_path);
  link::apply_overrides(o.link_overrides, options.link);
  // Without --link the vehicle has no link: whoever else flies on the domain is not ours.
  options.record_link = o.link || o.source_kind == "sim";
  // Nothing is taken from DDS then, so no keys are needed for the log's idle participant.
  if (!options.record_link) options.link.security.enabled = false;
  for (const std::string& file : {o.config_path, o.vehicle_path, o.camera_path}) {
    if (!file.empty()) options.attachments.push_back({config::resolve_data_path(file), ""});
  }
  auto recorder = std::make_unique<onboard_log::OnboardRecorder>(options);
  hq::log::note("{}: recording the flight to {}\n", g_program_name, recorder->path().c_str());
  for (const std::string& skipped : recorder->attachments_skipped()) {
    hq::log::note("{}: record attachment skipped: {}\n", g_program_name, skipped.c_str());
  }
  return recorder;
}

bool close_recorder(onboard_log::OnboardRecorder& recorder, mcap::KeyValues summary,
                    const link_bridge::LinkBridge* bridge) {
  summary["session_id"] =
      bridge != nullptr ? fmt::format("{:016x}", bridge->session_id()) : std::string("none");
  summary["duration_s"] = std::to_string(recorder.seconds_since_start());
  summary["steps_recorded"] = std::to_string(recorder.steps_pushed());
  summary["imu_samples_recorded"] = std::to_string(recorder.imu_pushed());
  const flight_log::RecorderReport& report = recorder.close(summary);
  onboard_log::print_report(stdout, report);
  const onboard_log::Ros2RecordReport& ros2 = recorder.ros2_report();
  onboard_log::print_report(stdout, ros2);
  if (!ros2.error.empty()) {
    hq::log::note("{}: the ROS 2 record is incomplete ({}); exit status {}\n", g_program_name,
                  ros2.error.c_str(), kRecordFailedExitStatus);
  }
  if (report.error.empty()) return ros2.error.empty();
  hq::log::note(
      "{}: the flight record is incomplete ({}); exit status {}, the flight "
      "itself went on\n",
      g_program_name, report.error.c_str(), kRecordFailedExitStatus);
  return false;
}

}  // namespace hq::onboard_app
