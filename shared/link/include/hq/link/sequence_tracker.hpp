#pragma once
/// Sequence numbers of one received stream (a vehicle session's states), read as a hint, not a
/// lock (as MAVLink's receivers do: they count loss by sequence, never drop by it forever).
///
/// A sample is accepted when it is next or a little ahead (lost ones counted as missing); one
/// behind the newest accepted (overtaken, replayed) or too far ahead (forged) is dropped. The
/// newest accepted number alone would be a lock: one forged sample far ahead makes every real
/// one after it "old". So the dropped samples are watched too: when a run of them from one
/// writer counts up consistently (each the previous + 1, with no sample accepted in between)
/// for resync_after_samples samples, or for two once the newest accepted one is older than
/// resync_after_ns, that run is the live stream and the tracker resynchronises on it. A single
/// overtaken or replayed sample never forms such a run.
///
/// What this cannot do: tell a forger that copies the session and keeps sending apart from the
/// vehicle; while it sends ahead, its stream is followed. Only the writer's identity can, and
/// that is DDS security's. Once it stops, the real stream is back within resync_after_samples.
///
/// Pure: data and time in, verdict out; allocation-free.

#include <cstdint>

namespace hq::link {

struct SequenceTrackerConfig {
  std::uint64_t max_forward_jump = 100'000;    ///< Further ahead than this: dropped.
  std::uint32_t resync_after_samples = 3;      ///< Consistent dropped run that resyncs.
  std::int64_t resync_after_ns = 500'000'000;  ///< Newest accepted this old: a run of 2 does.
};

enum class SequenceVerdict {
  kNext,    ///< Accepted, the next number (or the first sample).
  kGap,     ///< Accepted, ahead by up to max_forward_jump: `missing` were lost.
  kResync,  ///< Accepted: a consistent run of dropped samples replaced the stream followed.
  kBehind,  ///< Dropped: not newer than the newest accepted.
  kJump,    ///< Dropped: further ahead than max_forward_jump.
};

struct SequenceCheck {
  SequenceVerdict verdict = SequenceVerdict::kNext;
  std::uint64_t missing = 0;    ///< kGap: numbers skipped.
  std::uint64_t abandoned = 0;  ///< kResync: the newest number followed before it.
  [[nodiscard]] bool accepted() const {
    return verdict == SequenceVerdict::kNext || verdict == SequenceVerdict::kGap ||
           verdict == SequenceVerdict::kResync;
  }
};

class SequenceTracker {
 public:
  explicit SequenceTracker(const SequenceTrackerConfig& config = {}) : config_(config) {}

  /// One received sample: its sequence number, an identity of its writer (the DDS publication
  /// handle; 0 if unknown) and its receipt time on any monotonic clock.
  SequenceCheck check(std::uint64_t sequence, std::uint64_t writer, std::int64_t receipt_ns);
  /// Forgets the stream (a new session or another vehicle): the next sample is accepted.
  void reset();

  [[nodiscard]] bool started() const { return started_; }
  /// Newest accepted sequence number (meaningful once started()).
  [[nodiscard]] std::uint64_t last() const { return last_; }

 private:
  SequenceCheck accept(SequenceVerdict verdict, std::uint64_t sequence, std::int64_t receipt_ns);
  /// Extends or restarts the run of dropped samples; true when it is long enough to resync.
  bool run_resyncs(std::uint64_t sequence, std::uint64_t writer, std::int64_t receipt_ns);

  SequenceTrackerConfig config_;
  bool started_ = false;
  std::uint64_t last_ = 0;
  std::int64_t last_receipt_ns_ = 0;
  // The run of dropped samples that counts up consistently.
  std::uint32_t run_length_ = 0;
  std::uint64_t run_last_ = 0;
  std::uint64_t run_writer_ = 0;
};

}  // namespace hq::link
