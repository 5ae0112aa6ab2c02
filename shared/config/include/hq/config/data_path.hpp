#pragma once
/// Where the programs find the files they ship with (config/, calib/, onboard/sim/worlds/,
/// onboard/closed_loop/flights/, ground/config/), so that `hq-onboard` works from any folder,
/// from the build tree and installed alike.
///
/// A relative path is looked up, in order, in: the current folder (what the user typed wins);
/// $HQ_DATA_DIRS (colon-separated, for packagers and tests); <exe>/../share/haptiquad (an
/// installed tree, relocatable because it is found from /proc/self/exe, not a compiled-in
/// prefix); and, only for a program run from the build tree it was built in, the source tree
/// (running from build/ without installing). An installed program never looks in the source
/// tree, so whatever it reads by default must be installed. Every folder keeps the repository's
/// relative layout, so the same relative name works everywhere.

#include <filesystem>
#include <string>
#include <vector>

namespace hq::config {

/// The folders searched after the current one, in order (existing or not), for this program.
std::vector<std::filesystem::path> data_dirs();

/// The folders searched for a program whose executable is the absolute, symlink-free
/// `executable` (data_dirs() passes /proc/self/exe): $HQ_DATA_DIRS, `executable`'s
/// ../share/haptiquad, and the source tree only when `executable` is inside the build tree.
std::vector<std::filesystem::path> data_dirs_for_executable(
    const std::filesystem::path& executable);

/// `path` itself when it exists or is absolute; else the first data_dirs() entry holding it;
/// else `path` unchanged (the caller's "file not found" then names what the user gave).
std::string resolve_data_path(const std::string& path);

/// "looked in the current folder, A, B": for a not-found message.
std::string data_dirs_text();

}  // namespace hq::config
