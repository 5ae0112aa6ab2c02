#pragma once
/// A bounded single-producer single-consumer queue of trivially copyable samples: the frame
/// path (or the command tick) pushes, the recorder thread drains. Slots are allocated once;
/// push() never allocates, locks or blocks: a full queue refuses the sample and counts it.

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <vector>

namespace hq::flight_log {

template <class T>
class SpscQueue {
  static_assert(std::is_trivially_copyable_v<T>, "samples are copied into preallocated slots");

 public:
  /// capacity slots (at least 2), allocated here and never again.
  explicit SpscQueue(std::size_t capacity) : slots_(std::max<std::size_t>(capacity, 2)) {}
  SpscQueue(const SpscQueue&) = delete;
  SpscQueue& operator=(const SpscQueue&) = delete;

  /// Producer thread only. False (and counted in dropped()) when full.
  bool push(const T& sample) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= slots_.size()) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    slots_[head % slots_.size()] = sample;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  /// Consumer thread only: calls f(sample) for everything pushed so far, then frees the slots.
  template <class F>
  std::size_t drain(F&& f) {
    const std::size_t head = head_.load(std::memory_order_acquire);
    std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t n = head - tail;
    for (; tail != head; ++tail) f(slots_[tail % slots_.size()]);
    tail_.store(tail, std::memory_order_release);
    return n;
  }

  [[nodiscard]] std::size_t capacity() const noexcept { return slots_.size(); }
  /// Samples refused because the queue was full. Any thread.
  [[nodiscard]] std::uint64_t dropped() const noexcept {
    return dropped_.load(std::memory_order_relaxed);
  }

 private:
  std::vector<T> slots_;
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
  alignas(64) std::atomic<std::uint64_t> dropped_{0};
};

}  // namespace hq::flight_log
