#pragma once
/// Where the project's real data (the read-only shared/data folder) lives, for tests and tools.

#include <optional>
#include <string>

namespace hq::recording {

/// The first existing directory of $HQ_DATA_DIR and ../shared/data (relative to the current
/// directory, which is the repository root for tests), or nullopt if neither exists.
std::optional<std::string> find_data_dir();

/// The places find_data_dir() looks, for a GTEST_SKIP() or error message.
std::string data_dir_search_description();

}  // namespace hq::recording
