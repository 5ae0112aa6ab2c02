#pragma once
/// Text files of the TUM RGB-D benchmark (Sturm et al., IROS 2012): image lists (rgb.txt,
/// depth.txt), trajectories (groundtruth.txt, estimates) and accelerometer.txt, plus the
/// nearest-stamp association of colour and depth images that TUM's associate.py performs.
/// Seconds appear only here, at the file boundary; everything returned is stamped in t_ns.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace hq::recording {

/// One line of rgb.txt / depth.txt: stamp and path relative to the sequence directory.
struct TumListEntry {
  double t_s;
  std::string relative_path;
};

/// One associated colour/depth pair. t_ns is the colour stamp, which the frame is known by.
struct RgbdFrameFiles {
  std::int64_t t_ns;
  std::int64_t depth_t_ns;
  std::string rgb_path;    ///< Joined with the sequence directory (or absolute as listed).
  std::string depth_path;  ///< Likewise.
};

/// A pose of the sensor (camera or body, as the file says) in the world frame.
struct StampedPose {
  std::int64_t t_ns;
  Eigen::Isometry3d T_G_S;
};

/// Specific force measured by the accelerometer, sensor axes.
struct AccelSample {
  std::int64_t t_ns;
  Eigen::Vector3d accel_mps2;
};

/// Seconds to nanoseconds, rounded to the nearest ns. @pre t_s finite, |t_s| < 9.2e9.
std::int64_t seconds_to_ns(double t_s);
/// Nanoseconds to seconds (as exact as a double at that magnitude allows).
double ns_to_seconds(std::int64_t t_ns);

/// Reads rgb.txt / depth.txt: '#' comments, blank lines skipped, otherwise "timestamp filename"
/// with strictly increasing finite stamps. Throws hq::InputError naming path:line.
std::vector<TumListEntry> read_tum_list(const std::string& path);

/// Reads "t tx ty tz qx qy qz qw" lines (t in s, positions in m, quaternion normalised on
/// reading; a norm outside 1 +- 0.1 is rejected). Throws hq::InputError naming path:line for a
/// malformed line, a non-finite value, such a quaternion or a stamp not after the previous one.
std::vector<StampedPose> read_tum_trajectory(const std::string& path);

/// Writes poses in the format read_tum_trajectory reads: stamp with %.6f (TUM's microsecond
/// resolution), values with %.9g. Throws hq::InputError if the file cannot be written or a pose
/// is not finite.
void write_tum_trajectory(const std::string& path, const std::vector<StampedPose>& poses);

/// Reads accelerometer.txt: "t ax ay az" (s, m/s^2), same rules as read_tum_list.
std::vector<AccelSample> read_tum_accelerometer(const std::string& path);

/// Associates colour and depth entries as TUM's associate.py does: candidate pairs with
/// |dt| <= max_dt_s are taken greedily by increasing |dt|, each entry used at most once; the
/// result is sorted by colour stamp. Relative paths are joined to sequence_dir.
std::vector<RgbdFrameFiles> associate_rgbd(const std::vector<TumListEntry>& rgb,
                                           const std::vector<TumListEntry>& depth,
                                           const std::string& sequence_dir, double max_dt_s = 0.02);

}  // namespace hq::recording
