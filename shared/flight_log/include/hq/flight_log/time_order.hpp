#pragma once
/// Messages taken from several queues and DDS readers, handed to the MCAP writer in log-time
/// order, so each file's log times never go back (`mcap doctor`-clean; the spec asks readers to
/// sort otherwise). The log's thread takes link samples as they arrive and drains the local
/// queues every 100 ms or so, so what it takes is late by up to a drain period plus the chain's
/// own latency: each message is held until the horizon (the clock now minus a window) passes
/// it, then released oldest first, ties in arrival order. One arriving after a later one was
/// released (held longer than the window) is released at that later time and counted in late().
///
/// Storage is reserved at construction (a message table and a byte arena, whose held messages
/// are copied into a second arena when it runs out of room), so a flight that stays within it
/// allocates nothing; beyond `max_bytes` or `max_messages` the oldest messages are released early
/// (ordered still).

#include "hq/mcap/mcap.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

namespace hq::flight_log {

class TimeOrderBuffer {
 public:
  struct Message {
    std::uint16_t channel = 0;
    std::int64_t log_ns = 0;
    std::int64_t publish_ns = 0;
    mcap::Bytes data;
  };

  TimeOrderBuffer(std::size_t max_messages, std::size_t max_bytes)
      : max_messages_(std::max<std::size_t>(max_messages, 2)), max_bytes_(max_bytes) {
    held_.reserve(max_messages_);
    bytes_.reserve(max_bytes_);
    spare_.reserve(max_bytes_);
  }

  /// Copies the message in. When that would exceed the limits, the oldest half is released
  /// through out(const Message&) first.
  template <class Out>
  void add(std::uint16_t channel, std::int64_t log_ns, std::int64_t publish_ns, mcap::Bytes data,
           Out&& out) {
    if (bytes_.size() + data.size() > max_bytes_) compact();
    if (held_.size() >= max_messages_ || bytes_.size() + data.size() > max_bytes_) {
      sort();
      release_first(std::max<std::size_t>(held_.size() / 2, 1), out);
      compact();
    }
    held_.push_back({log_ns, publish_ns, arrivals_++, bytes_.size(), data.size(), channel});
    bytes_.insert(bytes_.end(), data.begin(), data.end());
  }

  /// Releases, oldest first, every held message with log_ns <= horizon_ns.
  template <class Out>
  void release(std::int64_t horizon_ns, Out&& out) {
    sort();
    const auto first_after = std::partition_point(
        held_.begin(), held_.end(), [&](const Held& h) { return h.log_ns <= horizon_ns; });
    release_first(static_cast<std::size_t>(first_after - held_.begin()), out);
  }

  template <class Out>
  void release_all(Out&& out) {
    release(std::numeric_limits<std::int64_t>::max(), out);
  }

  [[nodiscard]] std::size_t held() const noexcept { return held_.size(); }
  /// Messages that arrived after a later one had been released (restamped to its time).
  [[nodiscard]] std::uint64_t late() const noexcept { return late_; }
  /// The largest restamp of a late message (ns): how much longer the window would need to be.
  [[nodiscard]] std::int64_t late_max_ns() const noexcept { return late_max_ns_; }

 private:
  struct Held {
    std::int64_t log_ns;
    std::int64_t publish_ns;
    std::uint64_t arrival;
    std::size_t offset;
    std::size_t size;
    std::uint16_t channel;
  };

  void sort() {
    std::sort(held_.begin(), held_.end(), [](const Held& a, const Held& b) {
      return a.log_ns != b.log_ns ? a.log_ns < b.log_ns : a.arrival < b.arrival;
    });
  }

  template <class Out>
  void release_first(std::size_t n, Out& out) {
    if (n == 0) return;
    for (std::size_t i = 0; i < n; ++i) {
      const Held& h = held_[i];
      std::int64_t log_ns = h.log_ns;
      if (log_ns < last_released_ns_) {
        ++late_;
        late_max_ns_ = std::max(late_max_ns_, last_released_ns_ - log_ns);
        log_ns = last_released_ns_;
      }
      last_released_ns_ = log_ns;
      out(Message{h.channel, log_ns, h.publish_ns, {bytes_.data() + h.offset, h.size}});
    }
    held_.erase(held_.begin(), held_.begin() + static_cast<std::ptrdiff_t>(n));
    // The released bytes stay where they are until the arena runs out (add() compacts then):
    // copying what is still held on every release cost the writer thread a window's worth of
    // bytes per drain.
    if (held_.empty()) bytes_.clear();
  }

  // What is still held moves to the front of the spare arena, which becomes the arena.
  void compact() {
    spare_.clear();
    for (Held& h : held_) {
      const std::size_t offset = spare_.size();
      spare_.insert(spare_.end(), bytes_.begin() + static_cast<std::ptrdiff_t>(h.offset),
                    bytes_.begin() + static_cast<std::ptrdiff_t>(h.offset + h.size));
      h.offset = offset;
    }
    bytes_.swap(spare_);
  }

  std::size_t max_messages_;
  std::size_t max_bytes_;
  std::vector<Held> held_;
  std::vector<std::uint8_t> bytes_;
  std::vector<std::uint8_t> spare_;
  std::uint64_t arrivals_ = 0;
  std::int64_t last_released_ns_ = std::numeric_limits<std::int64_t>::min();
  std::uint64_t late_ = 0;
  std::int64_t late_max_ns_ = 0;
};

}  // namespace hq::flight_log
