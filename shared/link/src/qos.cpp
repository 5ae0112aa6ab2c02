#include "hq/link/qos.hpp"

#include "hq/base/error.hpp"

#include <string>
#include <utility>

namespace hq::link {

Qos::Qos() : qos_(dds_create_qos()) {
  if (qos_ == nullptr) throw InputError("dds_create_qos: out of memory");
}

Qos::~Qos() {
  if (qos_ != nullptr) dds_delete_qos(qos_);
}

Qos Qos::copy() const {
  Qos out;
  const dds_return_t rc = dds_copy_qos(out.get(), qos_);
  if (rc < 0) throw InputError(std::string("dds_copy_qos: ") + dds_strretcode(rc));
  return out;
}

Qos::Qos(Qos&& other) noexcept : qos_(std::exchange(other.qos_, nullptr)) {}

Qos& Qos::operator=(Qos&& other) noexcept {
  if (this != &other) {
    if (qos_ != nullptr) dds_delete_qos(qos_);
    qos_ = std::exchange(other.qos_, nullptr);
  }
  return *this;
}

namespace {

// Best-effort, keep-last-1, volatile: the shape of every periodic stream.
Qos latest_only() {
  Qos qos;
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  return qos;
}

// Reliable + transient-local keep-last-depth: late joiners get the last `depth` samples.
Qos kept(int depth) {
  Qos qos;
  // max_blocking_time bounds how long a write may wait for a full reliable history.
  dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, DDS_MSECS(100));
  dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, depth);
  dds_qset_durability(qos.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
  return qos;
}

}  // namespace

Qos command_qos(const LinkConfig& config, End end) {
  Qos qos = latest_only();
  dds_qset_deadline(qos.get(), config.command_deadline_ns);
  dds_qset_ownership(qos.get(), DDS_OWNERSHIP_EXCLUSIVE);
  // Manual-by-topic: liveliness is asserted by writing commands, so a station whose process is
  // alive but has stopped commanding loses ownership after one lease (automatic liveliness
  // would keep a hung operator loop in charge).
  dds_qset_liveliness(qos.get(), DDS_LIVELINESS_MANUAL_BY_TOPIC, config.command_lease_ns);
  if (end == End::kWriter) {
    dds_qset_ownership_strength(qos.get(), config.station_strength);
    // Keep the instance registered when a writer goes away so that ownership passes on
    // without an intermediate "disposed" state reaching the vehicle.
    dds_qset_writer_data_lifecycle(qos.get(), false);
  }
  return qos;
}

Qos mode_request_qos() { return kept(kModeRequestDepth); }

Qos event_qos() { return kept(kEventDepth); }

Qos vehicle_state_qos() { return latest_only(); }

Qos camera_qos() { return latest_only(); }

Qos heartbeat_qos(const LinkConfig& config) {
  Qos qos = latest_only();
  dds_qset_liveliness(qos.get(), DDS_LIVELINESS_AUTOMATIC, config.heartbeat_lease_ns);
  return qos;
}

}  // namespace hq::link
