#include "hq/link/sequence_tracker.hpp"

namespace hq::link {

SequenceCheck SequenceTracker::check(std::uint64_t sequence, std::uint64_t writer,
                                     std::int64_t receipt_ns) {
  if (!started_) return accept(SequenceVerdict::kNext, sequence, receipt_ns);
  if (sequence > last_ && sequence - last_ <= config_.max_forward_jump) {
    const std::uint64_t missing = sequence - last_ - 1;
    SequenceCheck out =
        accept(missing == 0 ? SequenceVerdict::kNext : SequenceVerdict::kGap, sequence, receipt_ns);
    out.missing = missing;
    return out;
  }
  const SequenceVerdict dropped =
      sequence <= last_ ? SequenceVerdict::kBehind : SequenceVerdict::kJump;
  if (!run_resyncs(sequence, writer, receipt_ns)) return SequenceCheck{dropped, 0, 0};
  const std::uint64_t abandoned = last_;
  SequenceCheck out = accept(SequenceVerdict::kResync, sequence, receipt_ns);
  out.abandoned = abandoned;
  return out;
}

SequenceCheck SequenceTracker::accept(SequenceVerdict verdict, std::uint64_t sequence,
                                      std::int64_t receipt_ns) {
  SequenceCheck out;
  out.verdict = verdict;
  started_ = true;
  last_ = sequence;
  last_receipt_ns_ = receipt_ns;
  // A run is of samples dropped one after another: an accepted one in between ends it, so the
  // stream followed keeps its place while it is live.
  run_length_ = 0;
  return out;
}

bool SequenceTracker::run_resyncs(std::uint64_t sequence, std::uint64_t writer,
                                  std::int64_t receipt_ns) {
  const bool same_writer = run_length_ > 0 && writer == run_writer_;
  if (same_writer && sequence == run_last_) return false;  // a duplicate neither adds nor breaks
  if (same_writer && sequence == run_last_ + 1) {
    ++run_length_;
  } else {
    run_length_ = 1;
    run_writer_ = writer;
  }
  run_last_ = sequence;
  if (run_length_ >= config_.resync_after_samples) return true;
  const bool stream_quiet = receipt_ns - last_receipt_ns_ >= config_.resync_after_ns;
  return stream_quiet && run_length_ >= 2;
}

void SequenceTracker::reset() {
  started_ = false;
  last_ = 0;
  last_receipt_ns_ = 0;
  run_length_ = 0;
  run_last_ = 0;
  run_writer_ = 0;
}

}  // namespace hq::link
