#pragma once
/// The vehicle's marker position as the console tells it: VehicleState.position_invalid_reason
/// (hq::navigation::PositionInvalid on the vehicle) in plain words.

#include <cstddef>
#include <cstdint>

namespace hq::console {

/// The position was valid once and the vehicle now says it is lost (reasons 2..4: no marker for
/// too long, uncertainty over its bound, markers disagreeing): the top view must neither follow
/// nor dead-reckon from it.
bool position_lost(std::uint8_t position_invalid_reason);

/// The reason in plain words, e.g. "no marker for 3.4 s", "position uncertainty 0.62 m",
/// "markers or velocity disagree with the
/// estimate", "no marker seen yet"; "" for 0 (valid or not said) and
/// "unknown reason N" beyond 4. Writes into out (hq::format_into: no allocation), returns out.
const char* position_invalid_text(std::uint8_t reason, float age_s, float sigma_m, char* out,
                                  std::size_t size);

}  // namespace hq::console
