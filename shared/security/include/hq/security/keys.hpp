#pragma once
/// DDS Security keys for the HaptiQuad link (OMG DDS Security 1.1, Cyclone DDS's builtin
/// authentication, access-control and crypto plugins), made and checked with OpenSSL.
///
/// A keys directory, as `hq-keys` lays it out:
///   ca.pem, ca.key.pem            the CA (identity CA and permissions CA are the same)
///   governance.xml, governance.p7s     domain and topic rules, S/MIME signed by the CA
///   <identity>/cert.pem, key.pem       e.g. vehicle_1/, station_2/: ECDSA P-256, signed by the CA
///   <identity>/permissions.xml, permissions.p7s   that identity's grant, signed by the CA
///
/// Governance: every hq_* topic has read and write access control and encrypted data and
/// metadata; discovery and liveliness are encrypted; unauthenticated participants are refused
/// and join access control is on.
///
/// Per-vehicle restriction. DDS permissions grant topics and partitions, never key values, and
/// every link topic is keyed by vehicle_id, so a grant per topic alone would let a station
/// listed for vehicle 1 command vehicle 2. A secured participant therefore puts every reader and
/// writer in the partition vehicle_partition(vehicle_id) ("hq_vehicle_<id>"), and permissions
/// grant topics only in the partitions of the vehicles named: a vehicle publishes its state,
/// camera, events and heartbeats and subscribes to commands, mode requests and heartbeats in
/// its own partition; a station does the reverse in the partitions of the vehicles it is listed
/// for, and also reads the commands and mode requests there, so that its flight record (MCAP)
/// holds what every station asked of its vehicle, not only its own. Access control refuses the
/// writer of a topic/partition not granted when it is created locally, and refuses to match a
/// remote one, so a station without a grant cannot deliver a single command.
///
/// Per-station identity. Every sample a station writes claims its station id, and a station
/// listed for a vehicle could claim another listed station's id. So a station's writers are
/// also in station_partition(vehicle_id, station_id) ("hq_vehicle_<v>_station_<s>"), which only
/// that station's permissions grant: Cyclone's access control refuses a writer whose partitions
/// are not all granted (locally and remotely), so the partitions a vehicle sees on a matched
/// writer name the certificate behind it. Readers stay in the vehicle partition (partitions
/// match when they share one), and the vehicle compares the sample's claimed station id with
/// its writer's station partition (hq/link/writer_binding.hpp).

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace hq::security {

/// Which end of the link an identity is.
enum class Role { kVehicle, kStation };

/// "hq_vehicle_<id>": the partition of every secured reader and writer of vehicle `id`.
std::string vehicle_partition(std::uint32_t vehicle_id);
/// "hq_vehicle_<vehicle_id>_station_<station_id>": the partition only station `station_id`'s
/// permissions grant among vehicle `vehicle_id`'s, which its writers add to the vehicle's.
std::string station_partition(std::uint32_t vehicle_id, std::uint32_t station_id);
/// The station id of a station partition of vehicle `vehicle_id`, 0 if `partition` is not one
/// (a station id is >= 1).
std::uint32_t station_of_partition(std::string_view partition, std::uint32_t vehicle_id);
/// "vehicle_<id>" or "station_<id>": the identity's folder name in a keys directory.
std::string identity_name(Role role, std::uint32_t id);
/// The certificate subject (and permissions subject_name), e.g. "CN=vehicle_1,O=HaptiQuad".
std::string subject_name(Role role, std::uint32_t id);

/// The files Cyclone's plugins read, as absolute or relative paths.
struct IdentityFiles {
  std::string identity_ca;     ///< CA that signed every identity certificate (PEM).
  std::string certificate;     ///< This participant's certificate (PEM).
  std::string private_key;     ///< Its private key (PEM, unencrypted).
  std::string governance;      ///< Signed governance document (S/MIME).
  std::string permissions;     ///< Signed permissions document of this identity (S/MIME).
  std::string permissions_ca;  ///< CA that signed governance and permissions (PEM).
};

/// The files of `identity` in a keys directory laid out by hq-keys.
IdentityFiles files_in(const std::string& keys_dir, const std::string& identity);

/// Validity of a certificate, in seconds since 1970 (UTC).
struct Validity {
  std::int64_t not_before_s = 0;
  std::int64_t not_after_s = 0;
};
/// From `now_s` - 60 s (clock skew between machines) for `days` days.
Validity valid_for_days(std::int64_t now_s, int days);

/// The largest domain id Cyclone's access-control plugin accepts in governance and permissions
/// (230, below the 232 of the default port mapping): secured links use domains 0..230.
inline constexpr int kMaxSecuredDomainId = 230;

/// DDS domain ids the governance and permissions cover.
struct DomainRange {
  int min_id = 0;
  int max_id = kMaxSecuredDomainId;
};

/// Makes `dir` (if absent) with ca.pem and ca.key.pem: an ECDSA P-256 key and a self-signed CA
/// certificate. Refuses to overwrite an existing CA. hq::InputError on any failure.
void make_ca(const std::string& dir, const Validity& validity);

/// Writes governance.xml and its signature governance.p7s (by the CA in `dir`).
void make_governance(const std::string& dir, const DomainRange& domains);

struct IdentityRequest {
  Role role = Role::kVehicle;
  std::uint32_t id = 1;
  /// Vehicles a station may command (ignored for a vehicle, which has only its own id).
  std::vector<std::uint32_t> vehicles;
  Validity validity;  ///< Of the certificate and of the permissions grant.
  DomainRange domains;
};

/// Makes `dir`/<identity_name>/ with key.pem, cert.pem (signed by the CA in `dir`),
/// permissions.xml and permissions.p7s. Overwrites an identity of that name.
void make_identity(const std::string& dir, const IdentityRequest& request);

/// The documents themselves (OMG DDS Security 1.1 §9.4.1.2 and §9.4.1.3), for tests and
/// inspection.
std::string governance_xml(const DomainRange& domains);
std::string permissions_xml(const IdentityRequest& request);

/// Checks what Cyclone would otherwise reject with a terse "Error" (or not at all): every file
/// exists and is readable; the certificate parses, is valid at `now_s` (not expired, not yet
/// valid), was signed by identity_ca and matches private_key; the CAs are valid at `now_s`;
/// governance and permissions are S/MIME signed by permissions_ca; the permissions grant the
/// certificate's subject (compared as X.509 names). Throws hq::InputError naming the file and
/// the problem.
void check_identity(const IdentityFiles& files, std::int64_t now_s);

/// One end of a secured link: a name for messages (e.g. "station_1") and its files.
struct Peer {
  std::string name;
  IdentityFiles files;
};

/// Whether the DDS Security handshake between `a` and `b` can succeed as far as their keys
/// decide (Cyclone only logs "handshake failed" and drops the peer): check_identity of each,
/// then each certificate chains to the identity CA the other trusts and each permissions
/// document verifies against the permissions CA the other trusts. Throws hq::InputError
/// "a handshake between A and B cannot succeed: A's certificate ... is signed by CA X, B trusts
/// CA Y" naming the files and the CAs' fingerprints.
void check_handshake(const Peer& a, const Peer& b, std::int64_t now_s);

/// As check_handshake, one way: a peer that trusts `peer_ca` (PEM) as its identity and
/// permissions CA, as hq-keys lays keys out, accepts `a`'s certificate and permissions.
void check_trusted_by(const Peer& a, const std::string& peer_ca, std::int64_t now_s);

}  // namespace hq::security
