#pragma once
/// Cyclone DDS on the loopback interface only, for the tests and benches that run both ends of
/// the link on this machine: their samples never leave it, and nothing on the network (nor
/// another engineer's DDS processes elsewhere) reaches them. Set before the first participant
/// is created; the programs a test starts inherit it. With a domain of the test's own, parallel
/// ctest runs and other engineers' processes on this machine do not see each other's samples.

#include <cstddef>
#include <cstdlib>
#include <functional>
#include <string>
#include <unistd.h>

namespace hq::testing {

/// The CYCLONEDDS_URI document restricting Cyclone DDS to the interface "lo".
inline constexpr const char* kLoopbackCycloneDdsUri =
    "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/>"
    "</Interfaces></General></Domain></CycloneDDS>";

/// Sets CYCLONEDDS_URI to kLoopbackCycloneDdsUri for this process and its children. A test
/// replaces any setting (keep_existing false); a bench keeps one the user gave it.
inline void use_loopback_dds(bool keep_existing = false) {
  setenv("CYCLONEDDS_URI", kLoopbackCycloneDdsUri, keep_existing ? 0 : 1);
}

/// A DDS domain id in [1, 200] of this process and, with salt_modulus > 0, of this test:
/// 1 + (pid + offset + hash(test_name) % salt_modulus) % 200. Each test binary uses its own
/// offset (and a test name where its tests run side by side) so that binaries ctest runs in
/// parallel rarely meet.
inline int private_domain_id(int offset, const std::string& test_name = {}, int salt_modulus = 0) {
  const int salt = salt_modulus > 0 ? static_cast<int>(std::hash<std::string>{}(test_name) %
                                                       static_cast<std::size_t>(salt_modulus))
                                    : 0;
  return 1 + (getpid() + salt + offset) % 200;
}

}  // namespace hq::testing
