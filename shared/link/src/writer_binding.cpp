#include "hq/link/writer_binding.hpp"

#include "hq/security/keys.hpp"

namespace hq::link {
namespace {

/// The station partition of `vehicle_id` among the writer's partitions; 0 if none, or if more
/// than one (no grant hq-keys writes allows that, so it is not trusted either).
std::uint32_t station_in_partitions(const dds_qos_t* qos, std::uint32_t vehicle_id) {
  std::uint32_t n = 0;
  char** names = nullptr;
  if (qos == nullptr || !dds_qget_partition(qos, &n, &names)) return 0;
  std::uint32_t station = 0;
  int found = 0;
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t id = security::station_of_partition(names[i], vehicle_id);
    if (id != 0) {
      station = id;
      ++found;
    }
    dds_free(names[i]);
  }
  dds_free(names);
  return found == 1 ? station : 0;
}

}  // namespace

WriterStation WriterBinding::station_of(dds_entity_t reader, const dds_sample_info_t& info) {
  if (!secured_) return {};
  const dds_instance_handle_t publication = info.publication_handle;
  for (const Entry& entry : cache_) {
    if (entry.publication == publication && publication != 0) return {true, entry.station_id};
  }
  ++lookups_;
  dds_builtintopic_endpoint_t* writer = dds_get_matched_publication_data(reader, publication);
  if (writer == nullptr) return {true, 0, false};  // gone: not remembered, not judged
  const std::uint32_t station = station_in_partitions(writer->qos, vehicle_id_);
  dds_builtintopic_free_endpoint(writer);
  cache_[next_slot_] = {publication, station};
  next_slot_ = (next_slot_ + 1) % kWriters;
  return {true, station};
}

}  // namespace hq::link
