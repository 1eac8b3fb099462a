// Lock-free hand-over between pipeline threads where only the newest value matters
// (docs/data-flow.md, "latest frame wins"): a triple buffer for frames and a seqlock for results.
#pragma once

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <type_traits>

namespace lipdrive {
namespace detail {

// std::atomic::wait has no timeout; the futex it is built on does. The waiter sleeps only
// while `word` still holds `expected`, so a wake between its check and its sleep is never lost.
inline void futex_wait(std::atomic<std::uint32_t>& word, std::uint32_t expected, std::chrono::nanoseconds timeout) {
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t) &&
                std::atomic<std::uint32_t>::is_always_lock_free);
  const timespec relative{static_cast<time_t>(timeout.count() / 1'000'000'000),
                          static_cast<long>(timeout.count() % 1'000'000'000)};
  ::syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAIT_PRIVATE, expected, &relative, nullptr, 0);
}

inline void futex_wake_all(std::atomic<std::uint32_t>& word) {
  ::syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&word), FUTEX_WAKE_PRIVATE, INT32_MAX, nullptr, nullptr, 0);
}

}  // namespace detail

/// A triple buffer: one writer fills slots and publishes them, one reader takes the newest
/// published slot. The writer never waits; a published slot the reader has not taken when
/// the next one is published is dropped (counted). Slots are preallocated by the caller's
/// Slot type, so a steady stream of equally sized frames allocates nothing.
template <class Slot>
class LatestFrame {
 public:
  /// Writer: the slot to fill next (only the writer touches it until publish()).
  Slot& back() { return slots_[back_]; }

  /// Writer: makes back() the newest slot and hands the writer a free one.
  void publish() {
    const std::uint32_t previous = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
    back_ = previous & kIndexMask;
    if (previous & kFresh)
      dropped_.fetch_add(1, std::memory_order_relaxed);
    else
      detail::futex_wake_all(middle_);  // the reader may be waiting for exactly this
  }

  /// Reader: the newest published slot, or nullptr when none arrives within `timeout`. The
  /// slot stays the reader's until the next take().
  const Slot* take(std::chrono::nanoseconds timeout) {
    std::uint32_t middle = middle_.load(std::memory_order_acquire);
    if (!(middle & kFresh)) {
      detail::futex_wait(middle_, middle, timeout);
      middle = middle_.load(std::memory_order_acquire);
      if (!(middle & kFresh)) return nullptr;
    }
    // Only the writer sets kFresh, so exchanging now takes a fresh slot (possibly a newer one).
    front_ = middle_.exchange(front_, std::memory_order_acq_rel) & kIndexMask;
    return &slots_[front_];
  }

  /// Published slots replaced before the reader took them.
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  static constexpr std::uint32_t kIndexMask = 3, kFresh = 4;

  std::array<Slot, 3> slots_{};
  std::uint32_t back_ = 0;                // writer's
  std::atomic<std::uint32_t> middle_{1};  // shared: index | kFresh
  std::uint32_t front_ = 2;               // reader's
  std::atomic<std::uint64_t> dropped_{0};
};

/// A seqlock: one writer publishes values of a trivially copyable T, any number of readers
/// copy the latest one without locks and without ever blocking the writer.
template <class T>
class Published {
  static_assert(std::is_trivially_copyable_v<T>);

 public:
  void publish(const T& value) {
    std::array<std::uint64_t, kWords> words{};
    std::memcpy(words.data(), &value, sizeof(T));
    const std::uint32_t sequence = sequence_.load(std::memory_order_relaxed);
    sequence_.store(sequence + 1, std::memory_order_relaxed);  // odd: a write is under way
    std::atomic_thread_fence(std::memory_order_release);
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(words[i], std::memory_order_relaxed);
    // Version 0 means "nothing published": after 2^31 publishes (the voice's 100 a second wrap
    // in 248 days) the count goes on at 1.
    sequence_.store(sequence + 2 == 0 ? 2 : sequence + 2, std::memory_order_release);
    detail::futex_wake_all(sequence_);
  }

  /// The latest value and its version (0: nothing published yet).
  std::uint32_t read(T& value) const {
    std::array<std::uint64_t, kWords> words{};
    std::uint32_t before = 0, after = 0;
    do {
      before = sequence_.load(std::memory_order_acquire);
      for (std::size_t i = 0; i < kWords; ++i) words[i] = words_[i].load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      after = sequence_.load(std::memory_order_relaxed);
    } while (before != after || (before & 1));
    std::memcpy(static_cast<void*>(&value), words.data(), sizeof(T));  // T is trivially copyable
    return before / 2;
  }

  /// The latest version (0: nothing published yet), without copying the value.
  std::uint32_t version() const { return sequence_.load(std::memory_order_acquire) / 2; }

  /// Waits until a version newer than `seen` is published or `timeout` passes.
  void wait_newer(std::uint32_t seen, std::chrono::nanoseconds timeout) {
    const std::uint32_t sequence = sequence_.load(std::memory_order_acquire);
    if (sequence / 2 == seen) detail::futex_wait(sequence_, sequence, timeout);
  }

 private:
  static constexpr std::size_t kWords = (sizeof(T) + 7) / 8;
  std::atomic<std::uint32_t> sequence_{0};
  std::array<std::atomic<std::uint64_t>, kWords> words_{};
};

/// A fixed ring from one producer thread to one consumer thread (the take recorder's rows and
/// its sound): push() never blocks or allocates, and a full ring drops the item and counts it;
/// the consumer takes what is queued, oldest first.
template <class T, std::size_t N>
class SingleProducerRing {
 public:
  /// Producer: queues a copy of `item`; false (counted in take_dropped()) when the ring is full.
  bool push(const T& item) {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) >= N) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    slots_[head % N] = item;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }
  /// Consumer: the oldest queued item, or nullptr.
  const T* front() const {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
    return tail == head_.load(std::memory_order_acquire) ? nullptr : &slots_[tail % N];
  }
  /// Consumer: `take(item)` for every queued item, oldest first; then they are gone.
  template <class Take>
  void consume(Take take) {
    const std::uint64_t head = head_.load(std::memory_order_acquire);
    for (std::uint64_t tail = tail_.load(std::memory_order_relaxed); tail != head; ++tail) take(slots_[tail % N]);
    tail_.store(head, std::memory_order_release);
  }
  /// Consumer: drops the oldest queued item (front() must have returned one).
  void pop() { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  /// Consumer: drops what is queued.
  void clear() { tail_.store(head_.load(std::memory_order_acquire), std::memory_order_release); }
  /// Items the ring dropped since the last call.
  std::uint64_t take_dropped() { return dropped_.exchange(0, std::memory_order_relaxed); }

 private:
  std::array<T, N> slots_{};
  std::atomic<std::uint64_t> head_{0}, tail_{0};  // written by push() / the consumer
  std::atomic<std::uint64_t> dropped_{0};
};

}  // namespace lipdrive
