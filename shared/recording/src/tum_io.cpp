#include "hq/recording/tum_io.hpp"

#include "hq/base/error.hpp"
#include "hq/base/format_into.hpp"

#include "line_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <tuple>

namespace hq::recording {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;
// Quaternions in TUM files are printed with 4 decimals, so their norms deviate by ~1e-4. A norm
// far from 1 means the columns are not "qx qy qz qw" (e.g. positions in their place).
constexpr double kQuaternionNormTolerance = 0.1;

std::string join(const std::string& dir, const std::string& relative) {
  const std::filesystem::path file(relative);
  if (dir.empty() || file.is_absolute()) return relative;
  return (std::filesystem::path(dir) / file).string();
}

}  // namespace

std::int64_t seconds_to_ns(double t_s) {
  HQ_ASSERT(std::isfinite(t_s) && std::abs(t_s) < 9.2e9);
  // t_s * 1e9 directly would round to a multiple of 256 ns at today's epoch (1.3e18 needs 61
  // bits); the fractional part alone is exact (Sterbenz) and keeps ns resolution.
  const double whole_s = std::floor(t_s);
  const double fraction_s = t_s - whole_s;
  return static_cast<std::int64_t>(whole_s) * kNsPerS + std::llround(fraction_s * 1e9);
}

double ns_to_seconds(std::int64_t t_ns) {
  std::int64_t whole_s = t_ns / kNsPerS;
  std::int64_t remainder_ns = t_ns % kNsPerS;
  if (remainder_ns < 0) {
    remainder_ns += kNsPerS;
    --whole_s;
  }
  return static_cast<double>(whole_s) + static_cast<double>(remainder_ns) * 1e-9;
}

std::vector<TumListEntry> read_tum_list(const std::string& path) {
  detail::LineReader reader(path);
  std::vector<TumListEntry> entries;
  while (reader.next()) {
    reader.expect_fields(2, "timestamp filename");
    const double t_s = reader.stamp_s();
    entries.push_back({t_s, std::string(reader.fields()[1])});
  }
  return entries;
}

std::vector<StampedPose> read_tum_trajectory(const std::string& path) {
  detail::LineReader reader(path);
  std::vector<StampedPose> poses;
  static constexpr const char* kNames[] = {"timestamp", "tx", "ty", "tz", "qx", "qy", "qz", "qw"};
  while (reader.next()) {
    reader.expect_fields(8, "timestamp tx ty tz qx qy qz qw");
    const double t_s = reader.stamp_s();
    double values[8];
    for (std::size_t i = 1; i < 8; ++i) values[i] = reader.number(i, kNames[i]);
    // Eigen's constructor order is (w, x, y, z); the file's is x y z w.
    Eigen::Quaterniond q_G_S(values[7], values[4], values[5], values[6]);
    const double norm = q_G_S.norm();
    if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
      char text[64];
      hq::format_into(text, "{:.6g}", norm);
      throw InputError(reader.where() + ": quaternion (qx qy qz qw) has norm " + text +
                       ", expected 1 within 0.1 (is the line \"t tx ty tz qx qy qz qw\"?)");
    }
    q_G_S.normalize();
    StampedPose pose{seconds_to_ns(t_s), Eigen::Isometry3d::Identity()};
    pose.T_G_S.linear() = q_G_S.toRotationMatrix();
    pose.T_G_S.translation() = Eigen::Vector3d(values[1], values[2], values[3]);
    poses.push_back(pose);
  }
  return poses;
}

void write_tum_trajectory(const std::string& path, const std::vector<StampedPose>& poses) {
  std::ofstream out(path);
  if (!out) throw InputError(path + ": cannot open for writing");
  out << "# timestamp tx ty tz qx qy qz qw\n";
  char line[256];
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Isometry3d& T = poses[i].T_G_S;
    if (!T.matrix().allFinite()) {
      throw InputError(path + ": pose " + std::to_string(i) + " (t_ns " +
                       std::to_string(poses[i].t_ns) + ") is not finite; nothing after it written");
    }
    const Eigen::Quaterniond q = Eigen::Quaterniond(T.rotation()).normalized();
    const Eigen::Vector3d& p = T.translation();
    hq::format_into(line, "{:.6f} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g} {:.9g}\n",
                    ns_to_seconds(poses[i].t_ns), p.x(), p.y(), p.z(), q.x(), q.y(), q.z(), q.w());
    out << line;
  }
  out.flush();
  if (!out) throw InputError(path + ": write failed");
}

std::vector<AccelSample> read_tum_accelerometer(const std::string& path) {
  detail::LineReader reader(path);
  std::vector<AccelSample> samples;
  while (reader.next()) {
    reader.expect_fields(4, "timestamp ax ay az");
    const std::int64_t t_ns = seconds_to_ns(reader.stamp_s());
    const Eigen::Vector3d accel_mps2(reader.number(1, "ax"), reader.number(2, "ay"),
                                     reader.number(3, "az"));
    samples.push_back({t_ns, accel_mps2});
  }
  return samples;
}

std::vector<RgbdFrameFiles> associate_rgbd(const std::vector<TumListEntry>& rgb,
                                           const std::vector<TumListEntry>& depth,
                                           const std::string& sequence_dir, double max_dt_s) {
  if (!(max_dt_s >= 0.0) || !std::isfinite(max_dt_s)) {
    throw InputError("associate_rgbd: max_dt_s = " + std::to_string(max_dt_s) +
                     ", expected finite and >= 0");
  }
  // Candidate pairs within the tolerance. Both lists are sorted (the readers enforce it), so a
  // sliding window finds them without comparing every pair.
  struct Candidate {
    double abs_dt_s;
    std::size_t rgb_index;
    std::size_t depth_index;
  };
  std::vector<Candidate> candidates;
  std::size_t first_depth = 0;
  for (std::size_t r = 0; r < rgb.size(); ++r) {
    const double t_s = rgb[r].t_s;
    while (first_depth < depth.size() && depth[first_depth].t_s < t_s - max_dt_s) ++first_depth;
    for (std::size_t d = first_depth; d < depth.size() && depth[d].t_s <= t_s + max_dt_s; ++d) {
      const double abs_dt_s = std::abs(depth[d].t_s - t_s);
      if (abs_dt_s <= max_dt_s) candidates.push_back({abs_dt_s, r, d});
    }
  }
  // Greedy by smallest |dt| as associate.py; ties broken by index so the result is deterministic.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return std::tie(a.abs_dt_s, a.rgb_index, a.depth_index) <
           std::tie(b.abs_dt_s, b.rgb_index, b.depth_index);
  });
  std::vector<bool> rgb_used(rgb.size(), false);
  std::vector<bool> depth_used(depth.size(), false);
  std::vector<std::pair<std::size_t, std::size_t>> matches;
  for (const Candidate& c : candidates) {
    if (rgb_used[c.rgb_index] || depth_used[c.depth_index]) continue;
    rgb_used[c.rgb_index] = true;
    depth_used[c.depth_index] = true;
    matches.emplace_back(c.rgb_index, c.depth_index);
  }
  std::sort(matches.begin(), matches.end());

  std::vector<RgbdFrameFiles> frames;
  frames.reserve(matches.size());
  for (const auto& [r, d] : matches) {
    frames.push_back({seconds_to_ns(rgb[r].t_s), seconds_to_ns(depth[d].t_s),
                      join(sequence_dir, rgb[r].relative_path),
                      join(sequence_dir, depth[d].relative_path)});
  }
  return frames;
}

}  // namespace hq::recording
