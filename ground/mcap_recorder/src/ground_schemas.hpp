#pragma once
/// JSON Schemas of the ground's own channels (/ground/haptics, /ground/link).

namespace hq::mcap_recorder {

inline constexpr const char* kHapticsSchema =
    R"j({"title":"hq_ground.Haptics","description":"The haptic loop at one command tick: )j"
    R"j(velocity command sent (H frame), device position and force rendered (D frame, NED)",)j"
    R"j("type":"object","properties":{"timestamp":{"type":"object"},)j"
    R"j("command_valid":{"type":"boolean"},"v_cmd_H_mps":{"type":"object"},)j"
    R"j("yaw_rate_cmd_radps":{"type":"number"},"p_D_m":{"type":"object"},)j"
    R"j("F_D_n":{"type":"object"}}})j";

inline constexpr const char* kLinkSchema =
    R"j({"title":"hq_ground.Link","description":"Link latency as the ground saw it at one )j"
    R"j(command tick (ms; -1: not known yet)","type":"object","properties":{)j"
    R"j("timestamp":{"type":"object"},"latency_ms":{"type":["number","null"]},)j"
    R"j("round_trip_ms":{"type":["number","null"]},"state_age_ms":{"type":["number","null"]}}})j";

}  // namespace hq::mcap_recorder
