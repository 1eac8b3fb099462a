// One audio input heard on a thread of its own: the loop the voice room and the LTC timecode
// share. It reads block after block and hands each to its owner's `hear`; it notes when the
// input is lost (the device gone, or the recording over) and stops at the end of a recording.
//
// Thread model: the AudioListener owns its AudioSource and the thread that reads it. `hear`
// runs on that thread and touches only what its owner gives it; the owner declares the
// listener after everything `hear` uses, so the destructor (stop, join) runs first. Any
// thread may read input_lost() and blocks().
#pragma once

#include "drivers/audio_source.hpp"

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <thread>

namespace lipdrive {

class AudioListener {
 public:
  using Hear = std::function<void(const AudioBlock&)>;

  /// Takes the input and starts hearing it on a thread named `thread_name`, under SCHED_FIFO at
  /// `realtime_priority` when it is above 0: the frame path's priority ([scheduling]), since
  /// the frame path's threads read what `hear` publishes through seqlocks and would spin on a
  /// half-written value while a writer of lower priority waits for their CPU. A refusal leaves
  /// it under the normal scheduler, as the frame path (which says so in the log).
  AudioListener(std::unique_ptr<AudioSource> input, const char* thread_name, int realtime_priority, Hear hear);
  ~AudioListener();
  AudioListener(const AudioListener&) = delete;
  AudioListener& operator=(const AudioListener&) = delete;

  /// The input's name, for logs and the status line.
  const std::string& input_name() const { return input_name_; }
  /// Any thread: the last read found the device gone or the recording over.
  bool input_lost() const { return input_lost_.load(std::memory_order_relaxed); }
  /// Any thread: blocks heard so far.
  std::uint64_t blocks() const { return blocks_.load(std::memory_order_relaxed); }

 private:
  void run();

  std::unique_ptr<AudioSource> input_;  // the thread's
  std::string input_name_;
  Hear hear_;
  std::atomic<std::uint64_t> blocks_{0};
  std::atomic<bool> input_lost_{false};
  std::atomic<bool> stop_{false};
  std::thread thread_;  // last: it uses the members above
};

}  // namespace lipdrive
