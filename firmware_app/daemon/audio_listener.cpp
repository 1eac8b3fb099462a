#include "firmware_app/daemon/audio_listener.hpp"

#include "drivers/thread_scheduling.hpp"

#include <chrono>

namespace lipdrive {
namespace {

// How long one read waits for sound before the thread looks at its stop flag again.
constexpr std::chrono::milliseconds kAudioWait{100};

}  // namespace

AudioListener::AudioListener(std::unique_ptr<AudioSource> input, const char* thread_name, int realtime_priority,
                             Hear hear)
    : input_(std::move(input)),
      input_name_(input_->describe()),
      hear_(std::move(hear)),
      thread_(&AudioListener::run, this) {
  schedule_thread(thread_, thread_name, realtime_priority);
}

AudioListener::~AudioListener() {
  stop_ = true;
  thread_.join();
}

void AudioListener::run() {
  AudioBlock block;
  while (!stop_.load(std::memory_order_relaxed)) {
    const AudioStatus status = input_->read(block, kAudioWait);
    input_lost_.store(status == AudioStatus::kDisconnected || status == AudioStatus::kEndOfStream,
                      std::memory_order_relaxed);
    if (status == AudioStatus::kEndOfStream) return;  // a recording's sound ended: nothing more to hear
    if (status != AudioStatus::kBlock) continue;
    hear_(block);
    blocks_.fetch_add(1, std::memory_order_relaxed);
  }
}

}  // namespace lipdrive
