#pragma once
// Shared by the two readers of a recording (CSV files, flight.mcap).

#include "hq/console/recording.hpp"

#include <string>

namespace hq::console {

inline void add_problem(Recording& r, const std::string& text) {
  if (r.problems.size() < Recording::kMaxProblems) r.problems.push_back(text);
  ++r.problem_count;
}

/// The recording in the flight record `mcap_path` (see load_recording()).
/// @throws hq::InputError as hq::mcap::McapReader.
Recording load_mcap_recording(const std::string& mcap_path);

}  // namespace hq::console
