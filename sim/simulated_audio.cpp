#include "sim/simulated_audio.hpp"

#include "drivers/audio_file.hpp"
#include "drivers/clock.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace lipdrive {

SimulatedClipAudio::SimulatedClipAudio(SimulatedAudioOptions options, ReplayClock* clock)
    : options_(std::move(options)), clock_(clock ? clock : &own_clock_) {
  if (options_.block_frames < 1 || options_.block_frames > kMaxAudioBlockFrames || options_.loop_s < 0 ||
      options_.disconnect_after_s < 0)
    throw std::invalid_argument("simulated audio: block size, loop or fault out of range");
  DecodedAudio track = decode_audio(options_.clip, options_.sample_rate);
  samples_ = std::move(track.samples);
  const double rate = options_.sample_rate;
  track_start_ = std::llround(track.start_s * rate);
  loop_samples_ = std::llround(options_.loop_s * rate);
  if (options_.disconnect_after_s > 0) {
    outage_begin_ = std::llround(options_.disconnect_after_s * rate);
    outage_end_ = outage_begin_ + std::llround(std::chrono::duration<double>(options_.reconnect).count() * rate);
  }
}

float SimulatedClipAudio::sample_at(std::int64_t timeline_sample) const {
  const std::int64_t in_pass = loop_samples_ > 0 ? timeline_sample % loop_samples_ : timeline_sample;
  const std::int64_t index = in_pass - track_start_;
  return index >= 0 && index < static_cast<std::int64_t>(samples_.size()) ? samples_[static_cast<std::size_t>(index)]
                                                                          : 0.0f;
}

AudioStatus SimulatedClipAudio::read(AudioBlock& block, std::chrono::milliseconds timeout) {
  const std::int64_t frames = options_.block_frames;
  const std::int64_t start_ns = clock_->start_ns();
  const auto sample_ns = [&](std::int64_t sample) {
    return start_ns + static_cast<std::int64_t>(static_cast<double>(sample) * 1e9 / options_.sample_rate);
  };
  if (loop_samples_ == 0 && next_block_ * frames >= track_start_ + static_cast<std::int64_t>(samples_.size()))
    return AudioStatus::kEndOfStream;
  if (!started_) {
    // A microphone opened after the replay began delivers the present, not the past.
    started_ = true;
    const auto since = static_cast<double>(std::max<std::int64_t>(monotonic_ns() - start_ns, 0));
    next_block_ = static_cast<std::int64_t>(since * 1e-9 * options_.sample_rate) / frames;
  }
  const std::int64_t timeout_ns = std::chrono::nanoseconds(timeout).count();
  const std::int64_t first = next_block_ * frames;
  if (first < outage_end_ && first + frames > outage_begin_) {
    // The microphone is away: its samples are lost; it is back once the outage has passed.
    const std::int64_t back_ns = sample_ns(outage_end_);
    if (back_ns - monotonic_ns() > timeout_ns) {
      std::this_thread::sleep_for(timeout);
      return AudioStatus::kDisconnected;
    }
    std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(back_ns)));
    next_block_ = (outage_end_ + frames - 1) / frames;
    return AudioStatus::kDisconnected;
  }
  const std::int64_t due = sample_ns(first + frames);
  if (due - monotonic_ns() > timeout_ns) {
    std::this_thread::sleep_for(timeout);
    return AudioStatus::kTimeout;
  }
  // steady_clock is CLOCK_MONOTONIC.
  std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(due)));
  for (std::int64_t i = 0; i < frames; ++i) block.samples[static_cast<std::size_t>(i)] = sample_at(first + i);
  block.frames = static_cast<int>(frames);
  block.sample_rate = options_.sample_rate;
  block.capture_time_ns = sample_ns(first);
  block.position = static_cast<std::uint64_t>(first);
  block.media_time_s = static_cast<double>(loop_samples_ > 0 ? first % loop_samples_ : first) / options_.sample_rate;
  ++next_block_;
  return AudioStatus::kBlock;
}

}  // namespace lipdrive
