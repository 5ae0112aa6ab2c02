#include "hq/base/error.hpp"
#include "hq/link/link.hpp"

#include <ctime>
#include <filesystem>
#include <string>
#include <unistd.h>

namespace hq::link {

dds_return_t check(dds_return_t rc, const char* operation, const std::string& entity,
                   const std::string& hint) {
  if (rc >= 0) return rc;
  std::string message = std::string(operation) + "(" + entity + "): " + dds_strretcode(rc);
  if (rc == DDS_RETCODE_NOT_ALLOWED_BY_SECURITY && !hint.empty()) message += ": " + hint;
  throw InputError(message);
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
void on_liveliness_lost(dds_entity_t writer, const dds_liveliness_lost_status_t status, void* arg) {
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

namespace {

dds_entity_t create_participant(int domain_id, const dds_qos_t* qos) {
  if (domain_id < 0 || domain_id > kMaxDomainId) return DDS_RETCODE_BAD_PARAMETER;
  return dds_create_participant(static_cast<dds_domainid_t>(domain_id), qos, nullptr);
}

std::string absolute(const std::string& path) {
  return std::filesystem::absolute(path).lexically_normal().string();
}

// The QoS properties that load and configure Cyclone's builtin security plugins.
Qos security_qos(const SecurityConfig& security, const security::IdentityFiles& files) {
  Qos qos;
  const auto plugin = [&](const char* kind, const char* file, const char* init,
                          const char* finalize) {
    const std::string path = security.library_dir + "/" + file;
    if (::access(path.c_str(), R_OK) != 0) {
      throw InputError(path +
                       ": DDS Security plugin missing (Debian package libddsc0debian; "
                       "or set link.security.library_dir)");
    }
    const std::string prefix = std::string("dds.sec.") + kind + ".library.";
    dds_qset_prop(qos.get(), (prefix + "path").c_str(), path.c_str());
    dds_qset_prop(qos.get(), (prefix + "init").c_str(), init);
    dds_qset_prop(qos.get(), (prefix + "finalize").c_str(), finalize);
  };
  plugin("auth", "libdds_security_auth.so", "init_authentication", "finalize_authentication");
  plugin("crypto", "libdds_security_crypto.so", "init_crypto", "finalize_crypto");
  plugin("access", "libdds_security_ac.so", "init_access_control", "finalize_access_control");
  const auto file = [&](const char* name, const std::string& path) {
    dds_qset_prop(qos.get(), name, ("file:" + absolute(path)).c_str());
  };
  file("dds.sec.auth.identity_ca", files.identity_ca);
  file("dds.sec.auth.identity_certificate", files.certificate);
  file("dds.sec.auth.private_key", files.private_key);
  file("dds.sec.access.governance", files.governance);
  file("dds.sec.access.permissions", files.permissions);
  file("dds.sec.access.permissions_ca", files.permissions_ca);
  return qos;
}

}  // namespace

security::IdentityFiles security_files(const LinkConfig& config, security::Role role) {
  const SecurityConfig& s = config.security;
  const std::uint32_t id = role == security::Role::kVehicle ? config.vehicle_id : config.station_id;
  const std::string identity = s.identity.empty() ? security::identity_name(role, id) : s.identity;
  security::IdentityFiles files;
  if (!s.keys_dir.empty()) files = security::files_in(s.keys_dir, identity);
  const auto take = [](std::string& dst, const std::string& src) {
    if (!src.empty()) dst = src;
  };
  take(files.identity_ca, s.identity_ca);
  take(files.certificate, s.certificate);
  take(files.private_key, s.private_key);
  take(files.governance, s.governance);
  take(files.permissions, s.permissions);
  take(files.permissions_ca, s.permissions_ca);
  return files;
}

std::string describe_security(const LinkConfig& config, security::Role role) {
  if (!config.security.enabled) return "plain DDS (--insecure)";
  if (!config.security.has_keys()) return "DDS Security, no keys configured";
  return "DDS Security, certificate " + security_files(config, role).certificate;
}

Participant::Participant(int domain_id)
    : entity_(check(create_participant(domain_id, nullptr), "dds_create_participant",
                    "domain " + std::to_string(domain_id))),
      domain_id_(domain_id) {}

Participant::Participant(const LinkConfig& config, security::Role role)
    : domain_id_(config.domain_id) {
  const std::string where = "domain " + std::to_string(config.domain_id);
  if (!config.security.enabled) {
    entity_ = Entity(
        check(create_participant(config.domain_id, nullptr), "dds_create_participant", where));
    return;
  }
  const char* role_flag = role == security::Role::kVehicle ? "vehicle" : "station";
  if (!config.security.has_keys()) {
    const std::string id =
        std::to_string(role == security::Role::kVehicle ? config.vehicle_id : config.station_id);
    throw InputError(
        std::string("link.security: DDS Security is on and no keys are configured. Make them "
                    "(hq-keys init KEYS && hq-keys identity KEYS --role ") +
        role_flag + " --id " + id +
        (role == security::Role::kStation ? " --vehicles " + std::to_string(config.vehicle_id)
                                          : std::string()) +
        ") and pass --security-dir KEYS (link.security.keys_dir), or, for the loopback demo and "
        "tests only, run plain DDS with --insecure (link.security.enabled: false)");
  }
  if (config.domain_id > security::kMaxSecuredDomainId) {
    throw InputError("link.domain_id = " + std::to_string(config.domain_id) +
                     ": a secured link needs a domain in [0, " +
                     std::to_string(security::kMaxSecuredDomainId) +
                     "] (the largest id Cyclone's access control accepts)");
  }
  const security::IdentityFiles files = security_files(config, role);
  security::check_identity(files, static_cast<std::int64_t>(std::time(nullptr)));
  const Qos qos = security_qos(config.security, files);
  const dds_entity_t handle = create_participant(config.domain_id, qos.get());
  if (handle < 0) {
    throw InputError("dds_create_participant(" + where + ", secured by " + files.certificate +
                     "): " + dds_strretcode(handle) +
                     ": Cyclone's security plugins refused the identity, governance or "
                     "permissions (e.g. permissions for another subject or domain; its log "
                     "says which); every participant of one process must use the same plugins");
  }
  entity_ = Entity(handle);
  partition_ = security::vehicle_partition(config.vehicle_id);
  if (role == security::Role::kStation) {
    station_partition_ = security::station_partition(config.vehicle_id, config.station_id);
    // A station writes its own topics in its vehicle's partition and its own station's.
    writer_grant_hint_ = "the permissions of " + files.certificate +
                         " do not grant writing this topic in partitions " + partition_ + " and " +
                         station_partition_ +
                         " (a station writes commands, mode requests and heartbeats only; is "
                         "station_id " +
                         std::to_string(config.station_id) +
                         " this certificate's station, and vehicle " +
                         std::to_string(config.vehicle_id) + " one it may command?)";
  } else {
    writer_grant_hint_ = "the permissions of " + files.certificate +
                         " do not grant this topic in partition " + partition_;
  }
}

Qos Participant::reader_qos(const Qos& qos) const {
  Qos out = qos.copy();
  if (!partition_.empty()) dds_qset_partition1(out.get(), partition_.c_str());
  return out;
}

Qos Participant::writer_qos(const Qos& qos) const {
  Qos out = qos.copy();
  if (station_partition_.empty()) {
    if (!partition_.empty()) dds_qset_partition1(out.get(), partition_.c_str());
    return out;
  }
  const char* partitions[] = {partition_.c_str(), station_partition_.c_str()};
  dds_qset_partition(out.get(), 2, partitions);
  return out;
}

GuardCondition::GuardCondition(const Participant& participant)
    : entity_(check(dds_create_guardcondition(participant.handle()), "dds_create_guardcondition",
                    "participant")) {}

void GuardCondition::set(bool triggered) {
  check(dds_set_guardcondition(entity_.handle(), triggered), "dds_set_guardcondition",
        "guard condition");
}

WaitSet::WaitSet(const Participant& participant)
    : entity_(
          check(dds_create_waitset(participant.handle()), "dds_create_waitset", "participant")) {}

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
