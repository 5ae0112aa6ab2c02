#pragma once
/// Where the programs find the files they ship with (config/, calib/, onboard/sim/worlds/,
/// onboard/closed_loop/flights/, ground/config/), so that `hq-onboard` works from any folder,
/// from the build tree and installed alike.
///
/// A relative path is looked up, in order, in: the current folder (what the user typed wins);
/// $HQ_DATA_DIRS (colon-separated, for packagers and tests); <exe>/../share/haptiquad (an
/// installed tree, relocatable because it is found from /proc/self/exe, not a compiled-in
/// prefix); the source tree the program was built from (running from build/ without
/// installing). Every folder keeps the repository's relative layout, so the same relative name
/// works everywhere.

#include <filesystem>
#include <string>
#include <vector>

namespace hq::config {

/// The folders searched after the current one, in order (existing or not).
std::vector<std::filesystem::path> data_dirs();

/// `path` itself when it exists or is absolute; else the first data_dirs() entry holding it;
/// else `path` unchanged (the caller's "file not found" then names what the user gave).
std::string resolve_data_path(const std::string& path);

/// "looked in the current folder, A, B": for a not-found message.
std::string data_dirs_text();

}  // namespace hq::config
