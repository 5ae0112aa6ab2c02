#include "hq/link/link.hpp"

#include <string>

#include "hq/base/error.hpp"

namespace hq::link {

dds_return_t check(dds_return_t rc, const char* operation, const std::string& entity) {
  if (rc >= 0) return rc;
  throw InputError(std::string(operation) + "(" + entity + "): " + dds_strretcode(rc));
}

void Entity::reset() {
  if (handle_ > 0) {
    // A child already deleted with its parent returns "Already Deleted"/"Bad Parameter": fine.
    dds_delete(handle_);
  }
  handle_ = 0;
}

namespace {

StatusHandler& handler_of(void* arg) { return *static_cast<StatusHandler*>(arg); }

void on_requested_deadline_missed(dds_entity_t reader,
                                  const dds_requested_deadline_missed_status_t status, void* arg) {
  handler_of(arg).on_requested_deadline_missed(reader, status);
}
void on_offered_deadline_missed(dds_entity_t writer,
                                const dds_offered_deadline_missed_status_t status, void* arg) {
  handler_of(arg).on_offered_deadline_missed(writer, status);
}
void on_liveliness_changed(dds_entity_t reader, const dds_liveliness_changed_status_t status,
                           void* arg) {
  handler_of(arg).on_liveliness_changed(reader, status);
}
void on_liveliness_lost(dds_entity_t writer, const dds_liveliness_lost_status_t status,
                        void* arg) {
  handler_of(arg).on_liveliness_lost(writer, status);
}
void on_subscription_matched(dds_entity_t reader, const dds_subscription_matched_status_t status,
                             void* arg) {
  handler_of(arg).on_subscription_matched(reader, status);
}
void on_publication_matched(dds_entity_t writer, const dds_publication_matched_status_t status,
                            void* arg) {
  handler_of(arg).on_publication_matched(writer, status);
}
void on_data_available(dds_entity_t reader, void* arg) {
  handler_of(arg).on_data_available(reader);
}

}  // namespace

Listener::Listener(StatusHandler& handler, std::uint32_t status_mask)
    : listener_(dds_create_listener(&handler)) {
  if (listener_ == nullptr) throw InputError("dds_create_listener: out of memory");
  if (status_mask & DDS_REQUESTED_DEADLINE_MISSED_STATUS) {
    dds_lset_requested_deadline_missed(listener_, on_requested_deadline_missed);
  }
  if (status_mask & DDS_OFFERED_DEADLINE_MISSED_STATUS) {
    dds_lset_offered_deadline_missed(listener_, on_offered_deadline_missed);
  }
  if (status_mask & DDS_LIVELINESS_CHANGED_STATUS) {
    dds_lset_liveliness_changed(listener_, on_liveliness_changed);
  }
  if (status_mask & DDS_LIVELINESS_LOST_STATUS) {
    dds_lset_liveliness_lost(listener_, on_liveliness_lost);
  }
  if (status_mask & DDS_SUBSCRIPTION_MATCHED_STATUS) {
    dds_lset_subscription_matched(listener_, on_subscription_matched);
  }
  if (status_mask & DDS_PUBLICATION_MATCHED_STATUS) {
    dds_lset_publication_matched(listener_, on_publication_matched);
  }
  if (status_mask & DDS_DATA_AVAILABLE_STATUS) {
    dds_lset_data_available(listener_, on_data_available);
  }
}

Listener::~Listener() {
  if (listener_ != nullptr) dds_delete_listener(listener_);
}

Participant::Participant(int domain_id)
    : entity_(check(domain_id < 0 || domain_id > kMaxDomainId ? DDS_RETCODE_BAD_PARAMETER
                                                              : dds_create_participant(
                                                                    static_cast<dds_domainid_t>(
                                                                        domain_id),
                                                                    nullptr, nullptr),
                    "dds_create_participant", "domain " + std::to_string(domain_id))),
      domain_id_(domain_id) {}

GuardCondition::GuardCondition(const Participant& participant)
    : entity_(check(dds_create_guardcondition(participant.handle()), "dds_create_guardcondition",
                    "participant")) {}

void GuardCondition::set(bool triggered) {
  check(dds_set_guardcondition(entity_.handle(), triggered), "dds_set_guardcondition",
        "guard condition");
}

WaitSet::WaitSet(const Participant& participant)
    : entity_(check(dds_create_waitset(participant.handle()), "dds_create_waitset",
                    "participant")) {}

void WaitSet::attach(dds_entity_t condition, dds_attach_t token) {
  check(dds_waitset_attach(entity_.handle(), condition, token), "dds_waitset_attach",
        "entity " + std::to_string(condition));
}

void WaitSet::detach(dds_entity_t condition) {
  check(dds_waitset_detach(entity_.handle(), condition), "dds_waitset_detach",
        "entity " + std::to_string(condition));
}

int WaitSet::wait(std::span<dds_attach_t> triggered, dds_duration_t timeout_ns) noexcept {
  const dds_return_t n =
      dds_waitset_wait(entity_.handle(), triggered.data(), triggered.size(), timeout_ns);
  if (n < 0) last_error_ = dds_strretcode(n);
  return n;
}

}  // namespace hq::link
