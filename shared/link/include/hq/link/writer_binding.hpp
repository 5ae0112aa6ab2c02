#pragma once
/// Which station wrote a sample, as DDS Security vouches for it.
///
/// A sample's station_id is a claim; on a secured link the writer's partitions are not: access
/// control lets a writer into station partition security::station_partition(vehicle, s) only
/// when station s's certificate and permissions created it (hq/security/keys.hpp). A vehicle
/// asks, per taken sample, for the station its writer is bound to and refuses a sample whose
/// claim differs (the Failsafe counts it as an intrusion).
///
/// Allocation: the first sample of a writer fetches its discovery data from Cyclone
/// (dds_get_matched_publication_data, which allocates, once per writer); later samples of it
/// hit a fixed cache, so the per-sample path allocates nothing.

#include <dds/dds.h>

#include <array>
#include <cstddef>
#include <cstdint>

namespace hq::link {

/// The station a writer is bound to: `bound` when the link is secured (the answer is the
/// certificate's); station_id 0 when bound and the writer holds no station partition of this
/// vehicle. `known` is false when the writer had left before its sample was checked (a station
/// restarting, a sample held by an emulated delay): nothing can be said of who wrote it.
struct WriterStation {
  bool bound = false;
  std::uint32_t station_id = 0;
  bool known = true;
};

class WriterBinding {
 public:
  /// `secured`: whether the reader's participant is (else every answer is unbound).
  WriterBinding(bool secured, std::uint32_t vehicle_id)
      : secured_(secured), vehicle_id_(vehicle_id) {}

  /// The station of the writer of the sample `info` describes, taken from `reader`.
  WriterStation station_of(dds_entity_t reader, const dds_sample_info_t& info);

  /// Writers looked up in Cyclone (cache misses).
  [[nodiscard]] std::uint64_t lookups() const { return lookups_; }

 private:
  struct Entry {
    dds_instance_handle_t publication = 0;
    std::uint32_t station_id = 0;
  };
  static constexpr std::size_t kWriters = 32;

  bool secured_;
  std::uint32_t vehicle_id_;
  std::array<Entry, kWriters> cache_{};
  std::size_t next_slot_ = 0;
  std::uint64_t lookups_ = 0;
};

}  // namespace hq::link
