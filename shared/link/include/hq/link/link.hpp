#pragma once
/// The DDS link: RAII types over Cyclone DDS's C API (participant, topic, writer, reader,
/// waitset, listener), plus the messages, QoS and configuration headers.
///
/// Every failing dds_* call during setup throws hq::InputError naming the call, the entity and
/// Cyclone's reason, e.g. "dds_create_writer(hq_velocity_command): Bad Parameter". The per-sample
/// calls (write, take, wait) return a status instead and keep the reason in last_error(), so the
/// hot paths throw nothing and allocate nothing.
///
/// Deleting a DDS entity deletes its children, so declare children after their participant
/// (destroyed first). Handles are never reused while the process lives, so deleting an already
/// deleted child is harmless.

#include "hq/link/config.hpp"
#include "hq/link/impairment.hpp"
#include "hq/link/messages.hpp"
#include "hq/link/qos.hpp"
#include "hq/security/keys.hpp"

#include <dds/dds.h>

#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace hq::link {

/// Returns `rc` if it is >= 0, else throws hq::InputError "operation(entity): reason", with
/// `hint` appended when the reason is Cyclone's "Not Allowed By Security".
dds_return_t check(dds_return_t rc, const char* operation, const std::string& entity,
                   const std::string& hint = {});

/// Owns one dds_entity_t and deletes it (with its children). Non-copyable, movable.
class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) : handle_(handle) {}
  ~Entity() { reset(); }
  Entity(Entity&& other) noexcept : handle_(std::exchange(other.handle_, 0)) {}
  Entity& operator=(Entity&& other) noexcept {
    if (this != &other) {
      reset();
      handle_ = std::exchange(other.handle_, 0);
    }
    return *this;
  }
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;

  [[nodiscard]] dds_entity_t handle() const { return handle_; }
  /// Deletes the entity now (no-op if empty).
  void reset();

 private:
  dds_entity_t handle_ = 0;
};

/// Callbacks for the statuses a Listener subscribes to. Called on a Cyclone thread: keep them
/// short, non-blocking and thread-safe. Must outlive every entity created with its Listener.
class StatusHandler {
 public:
  virtual ~StatusHandler() = default;
  virtual void on_requested_deadline_missed(dds_entity_t /*reader*/,
                                            const dds_requested_deadline_missed_status_t&) {}
  virtual void on_offered_deadline_missed(dds_entity_t /*writer*/,
                                          const dds_offered_deadline_missed_status_t&) {}
  virtual void on_liveliness_changed(dds_entity_t /*reader*/,
                                     const dds_liveliness_changed_status_t&) {}
  virtual void on_liveliness_lost(dds_entity_t /*writer*/, const dds_liveliness_lost_status_t&) {}
  virtual void on_subscription_matched(dds_entity_t /*reader*/,
                                       const dds_subscription_matched_status_t&) {}
  virtual void on_publication_matched(dds_entity_t /*writer*/,
                                      const dds_publication_matched_status_t&) {}
  virtual void on_data_available(dds_entity_t /*reader*/) {}
};

/// A dds_listener_t forwarding the statuses in `status_mask` (DDS_*_STATUS bits, e.g.
/// DDS_REQUESTED_DEADLINE_MISSED_STATUS | DDS_LIVELINESS_CHANGED_STATUS) to `handler`.
/// Entities copy the listener when created, so it may be destroyed afterwards; the handler
/// may not. Data-available is forwarded only if asked for, because a listener that handles it
/// resets the status that waitsets on status conditions would see.
class Listener {
 public:
  Listener(StatusHandler& handler, std::uint32_t status_mask);
  ~Listener();
  Listener(Listener&& other) noexcept : listener_(std::exchange(other.listener_, nullptr)) {}
  Listener& operator=(Listener&&) = delete;
  Listener(const Listener&) = delete;
  Listener& operator=(const Listener&) = delete;

  [[nodiscard]] const dds_listener_t* get() const { return listener_; }

 private:
  dds_listener_t* listener_;
};

/// The key files a secured participant of `role` uses: config.security's single paths where
/// set, else the hq-keys layout of keys_dir with identity (default vehicle_<vehicle_id> or
/// station_<station_id>). hq::InputError if a file is named by neither.
security::IdentityFiles security_files(const LinkConfig& config, security::Role role);

/// "DDS Security, certificate keys/vehicle_1/cert.pem" or "plain DDS (--insecure)", for the
/// programs' start-up line.
std::string describe_security(const LinkConfig& config, security::Role role);

/// A domain participant, configured by CYCLONEDDS_URI if set.
///
/// Secured (LinkConfig::security.enabled): before creating it, the key files are checked
/// (security::check_identity: present, readable, certificate valid now, signed by the CA,
/// matching its key, documents signed by the permissions CA; hq::InputError naming file and
/// problem), then Cyclone's authentication, access-control and crypto plugins are configured
/// through participant QoS properties (dds.sec.*). Every reader and writer made on a secured
/// participant is put in the partition security::vehicle_partition(vehicle_id), the unit the
/// permissions grant (see hq/security/keys.hpp for why); a station's writers also in its
/// station partition security::station_partition(vehicle_id, station_id), which binds what
/// they write to its certificate (writer_binding.hpp). A plain participant uses the default
/// partition, so plain and secured participants never exchange samples.
class Participant {
 public:
  /// Plain DDS on `domain_id` (0..kMaxDomainId).
  explicit Participant(int domain_id);
  /// On config.domain_id, secured as `role` unless config.security.enabled is false;
  /// hq::InputError naming what to do when security is on and no keys are configured.
  Participant(const LinkConfig& config, security::Role role);
  [[nodiscard]] dds_entity_t handle() const { return entity_.handle(); }
  [[nodiscard]] int domain_id() const { return domain_id_; }
  [[nodiscard]] bool secured() const { return !partition_.empty(); }
  /// `qos` for a reader of this participant (with the vehicle partition when secured).
  [[nodiscard]] Qos reader_qos(const Qos& qos) const;
  /// `qos` for a writer (with the vehicle partition, and a station's own, when secured).
  [[nodiscard]] Qos writer_qos(const Qos& qos) const;
  /// What a refused writer's error adds: which partitions it asked for, under which identity.
  [[nodiscard]] const std::string& writer_grant_hint() const { return writer_grant_hint_; }

 private:
  Entity entity_;
  int domain_id_;
  std::string partition_;
  std::string station_partition_;  ///< A secured station's own; empty otherwise.
  std::string writer_grant_hint_;
};

/// dds_create_topic with T's idlc descriptor; `name` defaults to TopicTraits<T>::kName.
template <typename T>
class Topic {
 public:
  explicit Topic(const Participant& participant, std::string name = TopicTraits<T>::kName)
      : name_(std::move(name)),
        entity_(check(dds_create_topic(participant.handle(), &TopicTraits<T>::descriptor(),
                                       name_.c_str(), nullptr, nullptr),
                      "dds_create_topic", name_)) {}
  [[nodiscard]] dds_entity_t handle() const { return entity_.handle(); }
  [[nodiscard]] const std::string& name() const { return name_; }

 private:
  std::string name_;
  Entity entity_;
};

/// Owns one message of type T whose sequence buffers are released with dds_sample_free. Use it
/// as preallocated storage for Reader<T>::take (buffers are reused once large enough) and for
/// samples with sequences to write. Non-copyable, movable.
template <typename T>
class Sample {
 public:
  Sample() = default;
  ~Sample() { dds_sample_free(&value_, &TopicTraits<T>::descriptor(), DDS_FREE_CONTENTS); }
  Sample(Sample&& other) noexcept : value_(other.value_) { other.value_ = T{}; }
  Sample& operator=(Sample&&) = delete;
  Sample(const Sample&) = delete;
  Sample& operator=(const Sample&) = delete;

  T& operator*() { return value_; }
  const T& operator*() const { return value_; }
  T* operator->() { return &value_; }
  const T* operator->() const { return &value_; }

 private:
  T value_{};
};

/// Gives an idlc sequence (dds_sequence_octet, dds_sequence_hq_msgs_Vector3f, ...) an owned
/// buffer of `capacity` elements, length 0, so that later takes and fills do not allocate.
template <typename Sequence>
void reserve(Sequence& sequence, std::uint32_t capacity) {
  using Element = std::remove_pointer_t<decltype(sequence._buffer)>;
  if (sequence._maximum >= capacity) return;
  if (sequence._release && sequence._buffer != nullptr) dds_free(sequence._buffer);
  sequence._buffer = static_cast<Element*>(dds_alloc(sizeof(Element) * capacity));
  sequence._maximum = capacity;
  sequence._length = 0;
  sequence._release = true;
}

/// Copies `src` into `dst`, whose buffer it owns (reserve() semantics): for deep copies into
/// preallocated samples.
template <typename Sequence>
void copy_sequence(Sequence& dst, const Sequence& src) {
  reserve(dst, src._length);
  if (src._length > 0) {
    std::memcpy(dst._buffer, src._buffer, sizeof(*src._buffer) * src._length);
  }
  dst._length = src._length;
}

/// Deep copy of a message into storage that owns its sequence buffers (a Sample<T>); the
/// fixed-size topics copy as structs.
template <typename T>
void copy_sample(T& dst, const T& src) {
  static_assert(std::is_trivially_copyable_v<T>);
  dst = src;
}
inline void copy_sample(VehicleState& dst, const VehicleState& src) {
  const auto points = dst.obstacle_points_B_m;
  const auto markers = dst.markers;
  dst = src;
  dst.obstacle_points_B_m = points;
  dst.markers = markers;
  copy_sequence(dst.obstacle_points_B_m, src.obstacle_points_B_m);
  copy_sequence(dst.markers, src.markers);
}
inline void copy_sample(CameraFrame& dst, const CameraFrame& src) {
  const auto jpeg = dst.rgb_jpeg;
  const auto depth = dst.depth_preview;
  dst = src;
  dst.rgb_jpeg = jpeg;
  dst.depth_preview = depth;
  copy_sequence(dst.rgb_jpeg, src.rgb_jpeg);
  copy_sequence(dst.depth_preview, src.depth_preview);
}

/// A data writer of T with the given QoS (see qos.hpp) and optional listener.
template <typename T>
class Writer {
 public:
  Writer(const Participant& participant, const Topic<T>& topic, const Qos& qos,
         const Listener* listener = nullptr)
      : name_(topic.name()),
        entity_(check(dds_create_writer(participant.handle(), topic.handle(),
                                        participant.writer_qos(qos).get(),
                                        listener != nullptr ? listener->get() : nullptr),
                      "dds_create_writer", name_, participant.writer_grant_hint())) {}

  /// Publishes `sample`; false on failure with the reason in last_error(). Allocates nothing
  /// for fixed-size types.
  bool write(const T& sample) noexcept { return ok(dds_write(entity_.handle(), &sample)); }
  /// Unregisters the instance keyed by `key_sample` (releases ownership of it at once).
  bool unregister(const T& key_sample) noexcept {
    return ok(dds_unregister_instance(entity_.handle(), &key_sample));
  }
  /// Blocks until every matched reliable reader acknowledged what was written, at most
  /// timeout_ns. True when all did (also with no reader matched); false on timeout or error.
  bool wait_for_acks(std::int64_t timeout_ns) noexcept {
    return ok(dds_wait_for_acks(entity_.handle(), timeout_ns));
  }
  /// Readers currently matched.
  [[nodiscard]] std::uint32_t matched_readers() const {
    dds_publication_matched_status_t status{};
    check(dds_get_publication_matched_status(entity_.handle(), &status),
          "dds_get_publication_matched_status", name_);
    return status.current_count;
  }
  [[nodiscard]] const char* last_error() const { return last_error_; }
  [[nodiscard]] dds_entity_t handle() const { return entity_.handle(); }

 private:
  bool ok(dds_return_t rc) noexcept {
    if (rc >= 0) return true;
    last_error_ = dds_strretcode(rc);
    return false;
  }
  std::string name_;
  Entity entity_;
  const char* last_error_ = "";
};

/// A data reader of T with the given QoS and optional listener. take() deserialises into
/// caller-owned storage (dds_take with a non-null buffer, not a loan), so a sample of a
/// fixed-size type costs no heap allocation, and sequences reuse a buffer reserved once.
template <typename T>
class Reader {
 public:
  Reader(const Participant& participant, const Topic<T>& topic, const Qos& qos,
         const Listener* listener = nullptr)
      : name_(topic.name()),
        entity_(check(dds_create_reader(participant.handle(), topic.handle(),
                                        participant.reader_qos(qos).get(),
                                        listener != nullptr ? listener->get() : nullptr),
                      "dds_create_reader", name_)) {}

  /// Takes the oldest valid sample of any instance into `sample`; false if none (or on error,
  /// with the reason in last_error()). Dispose/unregister notifications are consumed silently.
  bool take(T& sample, dds_sample_info_t& info) noexcept {
    return take_from(sample, info, DDS_HANDLE_NIL);
  }
  /// As take(), from one instance (vehicle) only; see lookup_instance().
  bool take_instance(T& sample, dds_sample_info_t& info, dds_instance_handle_t instance) noexcept {
    return take_from(sample, info, instance);
  }
  /// The instance handle of the key in `key_sample` (DDS_HANDLE_NIL if never seen).
  [[nodiscard]] dds_instance_handle_t lookup_instance(const T& key_sample) const {
    return dds_lookup_instance(entity_.handle(), &key_sample);
  }
  /// Writers currently matched.
  [[nodiscard]] std::uint32_t matched_writers() const {
    dds_subscription_matched_status_t status{};
    check(dds_get_subscription_matched_status(entity_.handle(), &status),
          "dds_get_subscription_matched_status", name_);
    return status.current_count;
  }
  [[nodiscard]] const char* last_error() const { return last_error_; }
  [[nodiscard]] dds_entity_t handle() const { return entity_.handle(); }
  [[nodiscard]] const std::string& name() const { return name_; }

  /// Impairs this reader (impairment.hpp): from now on take() hands a sample out only at its
  /// impaired arrival time on dds_time()'s clock, reordered by jitter, or never if dropped.
  /// Sizes the stage's ring of `capacity` samples once; their sequence buffers grow on first use.
  void impair(const ImpairmentConfig& config, std::uint32_t salt, std::size_t capacity = 64) {
    impairment_ = Impairment(config, salt);
    held_ = std::vector<Held>(config.active() ? capacity : 0);
  }
  [[nodiscard]] const Impairment& impairment() const { return impairment_; }
  /// Samples the impairment ring had to drop because it was full.
  [[nodiscard]] std::uint64_t impairment_overflows() const { return overflows_; }

 private:
  bool take_from(T& sample, dds_sample_info_t& info, dds_instance_handle_t instance) noexcept {
    if (!held_.empty()) return take_impaired(sample, info, instance);
    void* buffer = &sample;
    for (;;) {
      const dds_return_t n =
          instance == DDS_HANDLE_NIL
              ? dds_take(entity_.handle(), &buffer, &info, 1, 1)
              : dds_take_instance(entity_.handle(), &buffer, &info, 1, 1, instance);
      if (n < 0) {
        last_error_ = dds_strretcode(n);
        return false;
      }
      if (n == 0) return false;
      if (info.valid_data) return true;
    }
  }

  /// Drains DDS into the ring (each sample admitted or dropped), then hands out the due sample
  /// with the earliest impaired arrival.
  bool take_impaired(T& sample, dds_sample_info_t& info, dds_instance_handle_t instance) noexcept {
    const std::int64_t now_ns = dds_time();
    for (;;) {
      Held* slot = nullptr;
      for (Held& h : held_) {
        if (!h.live) {
          slot = &h;
          break;
        }
        if (slot == nullptr || h.release_ns < slot->release_ns) slot = &h;
      }
      // Full: the sample due first gives way, if DDS has a new one (counted below).
      const bool evicting = slot->live;
      const dds_sample_info_t kept_info = slot->info;
      void* buffer = &*slot->sample;
      const dds_return_t n =
          instance == DDS_HANDLE_NIL
              ? dds_take(entity_.handle(), &buffer, &slot->info, 1, 1)
              : dds_take_instance(entity_.handle(), &buffer, &slot->info, 1, 1, instance);
      if (n <= 0) {
        if (n < 0) last_error_ = dds_strretcode(n);
        slot->info = kept_info;
        break;
      }
      if (evicting) ++overflows_;
      slot->live = slot->info.valid_data && impairment_.admit(now_ns, slot->release_ns);
    }
    Held* due = nullptr;
    for (Held& h : held_) {
      if (!h.live || h.release_ns > now_ns) continue;
      if (instance != DDS_HANDLE_NIL && h.info.instance_handle != instance) continue;
      if (due == nullptr || h.release_ns < due->release_ns) due = &h;
    }
    if (due == nullptr) return false;
    copy_sample(sample, *due->sample);
    info = due->info;
    due->live = false;
    return true;
  }

  struct Held {
    Sample<T> sample;
    dds_sample_info_t info{};
    std::int64_t release_ns = 0;
    bool live = false;
  };

  std::string name_;
  Entity entity_;
  const char* last_error_ = "";
  Impairment impairment_;
  std::vector<Held> held_;
  std::uint64_t overflows_ = 0;
};

/// A read condition on a reader (triggers while it holds samples of any state).
class ReadCondition {
 public:
  template <typename T>
  explicit ReadCondition(const Reader<T>& reader)
      : entity_(check(dds_create_readcondition(reader.handle(), DDS_ANY_STATE),
                      "dds_create_readcondition", reader.name())) {}
  [[nodiscard]] dds_entity_t handle() const { return entity_.handle(); }

 private:
  Entity entity_;
};

/// A guard condition, e.g. to wake a waiting thread for shutdown.
class GuardCondition {
 public:
  explicit GuardCondition(const Participant& participant);
  /// Sets (true) or clears (false) the condition.
  void set(bool triggered);
  [[nodiscard]] dds_entity_t handle() const { return entity_.handle(); }

 private:
  Entity entity_;
};

/// A waitset: attach conditions (or entities, whose status changes then trigger it) with a token,
/// then block in wait() until one triggers — no sleep-polling.
class WaitSet {
 public:
  explicit WaitSet(const Participant& participant);
  /// Attaches `condition`; wait() reports `token` when it triggers.
  void attach(dds_entity_t condition, dds_attach_t token);
  void detach(dds_entity_t condition);
  /// Blocks up to `timeout_ns` (DDS_INFINITY for ever); writes the tokens of triggered
  /// conditions to `triggered` and returns their number (0 on timeout, < 0 on error, reason in
  /// last_error()).
  int wait(std::span<dds_attach_t> triggered, dds_duration_t timeout_ns) noexcept;
  [[nodiscard]] const char* last_error() const { return last_error_; }
  [[nodiscard]] dds_entity_t handle() const { return entity_.handle(); }

 private:
  Entity entity_;
  const char* last_error_ = "";
};

/// Every HaptiQuad topic on one participant: what a station and a vehicle both create before
/// their readers and writers (declare it before them, so it is built first).
struct Topics {
  explicit Topics(const Participant& participant)
      : command(participant),
        mode_request(participant),
        heartbeat(participant),
        vehicle_state(participant),
        camera(participant),
        event(participant) {}
  Topic<VelocityCommand> command;
  Topic<ModeRequest> mode_request;
  Topic<Heartbeat> heartbeat;
  Topic<VehicleState> vehicle_state;
  Topic<CameraFrame> camera;
  Topic<Event> event;
};

}  // namespace hq::link
