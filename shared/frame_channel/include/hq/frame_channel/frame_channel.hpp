#pragma once
/// RGB-D frames from hq-sim --sitl to hq-onboard on the same host, through POSIX shared memory
/// (shm_open + mmap) rather than DDS: a 640x480 BGR-D frame is ~0.9 MB, which DDS over UDP would
/// fragment 30 times a second, and SITL is same-host by nature.
///
/// Layout of `/hq-<name>`: a header (magic, version, geometry, intrinsics, the writer's pid and
/// generation, a heartbeat stamp, the count of published frames) and a ring of kSlots slots.
/// Each slot is guarded by a seqlock (odd while the single writer fills it): the writer never
/// waits, a reader copies and retries when the sequence moved under it. Nothing allocates after
/// construction on either side.

#include <opencv2/core.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

namespace hq::frame_channel {

/// `--channel` default on both sides: /hq-sitl.
inline constexpr const char* kDefaultChannelName = "sitl";
inline constexpr int kSlots = 4;

/// Simulator truth riding with a frame, for telemetry and evaluation; only simulation fills it.
struct SitlTruth {
  std::array<double, 3> v_H_mps{};  ///< Velocity in H (NED, yaw only; core paper §3).
  std::array<double, 3> p_W_m{};    ///< Body position in the simulator's world W (NWU).
  bool on_ground = true;
};

/// What the writer publishes once: image geometry and pinhole intrinsics (pixels).
struct ChannelGeometry {
  int width = 0;
  int height = 0;
  int channels = 1;  ///< 1: gray CV_8UC1, 3: BGR CV_8UC3. Depth is always CV_32FC1 metres.
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;
};

/// The stamp and metadata of a taken frame.
struct FrameInfo {
  std::uint64_t index = 0;  ///< 0, 1, 2, ... in publish order of this writer.
  std::int64_t t_ns = 0;    ///< CLOCK_MONOTONIC of the exposure.
  bool has_truth = false;
  SitlTruth truth;
};

/// "/hq-<name>"; throws hq::InputError unless name is 1..200 of [A-Za-z0-9._-].
std::string shm_name(const std::string& name);
/// One mmap of a channel's shared object (no heap: a reader remaps without allocating).
struct Mapping {
  void* base = nullptr;
  std::size_t bytes = 0;
};

/// The single producer. Creates /hq-<name>; throws hq::InputError when the geometry is invalid,
/// when a live writer (another process) already owns the name, or when shm_open/ftruncate/mmap
/// fail (naming the call and errno). A stale object left by a dead writer is replaced.
/// The destructor marks the channel closed and unlinks it.
class FrameChannelWriter {
 public:
  FrameChannelWriter(const std::string& name, const ChannelGeometry& geometry);
  /// Geometry without intrinsics (fx = fy = 0): for tests and channels that carry none.
  FrameChannelWriter(const std::string& name, int width, int height, int channels);
  ~FrameChannelWriter();
  FrameChannelWriter(const FrameChannelWriter&) = delete;
  FrameChannelWriter& operator=(const FrameChannelWriter&) = delete;

  /// Copies one frame into the next slot. image: CV_8UC(channels), depth_m: CV_32FC1, both of the
  /// channel's size; truth optional. Returns false (publishing nothing) on a type or size
  /// mismatch. Also refreshes the heartbeat. Lock-free, never waits; allocates nothing.
  bool publish(std::int64_t t_ns, const cv::Mat& image, const cv::Mat& depth_m,
               const SitlTruth* truth);
  /// Refreshes the heartbeat without a frame (a writer that is alive but has nothing to send).
  void heartbeat();
  /// Publishes the CLOCK_MONOTONIC of the writer's time zero; hq-sim --sitl: simulated t = 0,
  /// the boot of the flight controller it plays, so a reader maps the FC's MAVLink time_usec
  /// onto frame stamps exactly: t_ns = time_origin_ns + 1000 * time_usec.
  void set_time_origin(std::int64_t time_origin_ns);

  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] const ChannelGeometry& geometry() const { return geometry_; }
  [[nodiscard]] std::uint64_t published() const { return published_; }

 private:
  std::string name_;
  ChannelGeometry geometry_;
  Mapping map_;
  std::uint64_t published_ = 0;
};

struct ReaderOptions {
  /// A writer whose heartbeat is older than this counts as gone.
  std::int64_t dead_after_ns = 1'000'000'000;
  /// While the writer is gone, take_latest() looks for a restarted one at most this often.
  std::int64_t reopen_interval_ns = 200'000'000;
  /// Width and height the reader expects; 0: any.
  int expect_width = 0;
  int expect_height = 0;
};

/// A consumer (any number may read one channel). Throws hq::InputError naming the shm name when
/// the channel does not exist, is not a frame channel, has another version, or has another
/// geometry than expected.
class FrameChannelReader {
 public:
  explicit FrameChannelReader(const std::string& name, const ReaderOptions& options = {});
  ~FrameChannelReader();
  FrameChannelReader(const FrameChannelReader&) = delete;
  FrameChannelReader& operator=(const FrameChannelReader&) = delete;

  /// Copies the newest complete frame not taken yet into image (CV_8UC(channels)) and depth_m
  /// (CV_32FC1), resized only on the first call; true if there was one. Retries when the
  /// writer reused the slot during the copy, so a frame is never torn. Counts frames published
  /// between two takes as missed. Checks the writer's heartbeat; when the writer is gone, looks
  /// for a restarted one (same name, new pid or generation) and follows it. Allocates nothing
  /// after the first call.
  bool take_latest(cv::Mat& image, cv::Mat& depth_m, FrameInfo& info);

  /// False once the writer closed the channel or its heartbeat is older than dead_after_ns
  /// (as of the last take_latest()).
  [[nodiscard]] bool writer_alive() const { return writer_alive_; }
  [[nodiscard]] const ChannelGeometry& geometry() const { return geometry_; }
  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] int writer_pid() const;
  /// The writer's set_time_origin(); 0 until it set one.
  [[nodiscard]] std::int64_t time_origin_ns() const;
  [[nodiscard]] std::uint64_t frames_taken() const { return taken_; }
  [[nodiscard]] std::uint64_t frames_missed() const { return missed_; }
  /// Copies that the writer overwrote mid-copy and were retried.
  [[nodiscard]] std::uint64_t retries() const { return retries_; }
  /// Times a restarted writer was picked up.
  [[nodiscard]] std::uint64_t writer_restarts() const { return restarts_; }

 private:
  void check_writer(std::int64_t now_ns);
  bool try_reopen();

  std::string name_;
  ReaderOptions options_;
  ChannelGeometry geometry_;
  Mapping map_;
  bool writer_alive_ = true;
  bool have_taken_ = false;
  std::uint64_t last_index_ = 0;
  std::uint64_t taken_ = 0;
  std::uint64_t missed_ = 0;
  std::uint64_t retries_ = 0;
  std::uint64_t restarts_ = 0;
  std::int64_t last_reopen_ns_ = 0;
};

}  // namespace hq::frame_channel
