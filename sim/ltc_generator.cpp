#include "sim/ltc_generator.hpp"

#include "core/audio_rates.hpp"
#include "drivers/clock.hpp"

#include <ltc.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>
#include <thread>

namespace lipdrive {
namespace {

LTC_TV_STANDARD tv_standard(TimecodeRate rate) {
  switch (rate) {
    case TimecodeRate::k24: return LTC_TV_FILM_24;
    case TimecodeRate::k25: return LTC_TV_625_50;
    case TimecodeRate::k29_97DropFrame:
    case TimecodeRate::k30: return LTC_TV_525_60;
  }
  return LTC_TV_625_50;
}

}  // namespace

LtcGenerator::LtcGenerator(int sample_rate, TimecodeRate rate, std::int32_t start_frame, double level_dbfs)
    : rate_(rate), frame_(start_frame) {
  encoder_ = ltc_encoder_create(sample_rate, frame_rate(rate).fps(), tv_standard(rate), 0);
  if (!encoder_) throw std::runtime_error("libltc: cannot create an LTC encoder");
  ltc_encoder_set_volume(encoder_, level_dbfs);
  const Timecode label = timecode_from_frame(start_frame, rate);
  SMPTETimecode time{};
  time.hours = static_cast<unsigned char>(label.hours);
  time.mins = static_cast<unsigned char>(label.minutes);
  time.secs = static_cast<unsigned char>(label.seconds);
  time.frame = static_cast<unsigned char>(label.frames);
  ltc_encoder_set_timecode(encoder_, &time);
  if (is_drop_frame(rate)) {
    LTCFrame frame;
    ltc_encoder_get_frame(encoder_, &frame);
    frame.dfbit = 1;
    ltc_encoder_set_frame(encoder_, &frame);
  }
  samples_.reserve(ltc_encoder_get_buffersize(encoder_));
}

LtcGenerator::~LtcGenerator() { ltc_encoder_free(encoder_); }

std::span<const float> LtcGenerator::next_frame() {
  ltc_encoder_encode_frame(encoder_);
  ltcsnd_sample_t* buffer = nullptr;
  const int size = ltc_encoder_get_bufferptr(encoder_, &buffer, 1);
  samples_.resize(static_cast<std::size_t>(std::max(size, 0)));
  // libltc writes unsigned 8-bit audio centred on 128.
  for (std::size_t i = 0; i < samples_.size(); ++i) samples_[i] = (static_cast<float>(buffer[i]) - 128.0f) / 127.0f;
  ltc_encoder_inc_timecode(encoder_);
  frame_ = static_cast<std::int32_t>((frame_ + 1) % frames_per_day(rate_));
  return samples_;
}

SimulatedLtcAudio::SimulatedLtcAudio(SimulatedLtcOptions options)
    : options_(options), generator_(options.sample_rate, options.rate, [&] {
        const auto frame = frame_from_timecode(options.start, options.rate);
        if (!frame) throw std::invalid_argument("simulated LTC: the start is not a timecode at this rate");
        return *frame;
      }()) {
  if (options_.sample_rate < kMinAudioSampleRate || options_.sample_rate > kMaxAudioSampleRate ||
      options_.block_frames < 1 || options_.block_frames > kMaxAudioBlockFrames)
    throw std::invalid_argument("simulated LTC: sample rate or block size out of range");
}

std::string SimulatedLtcAudio::describe() const {
  const std::string_view what = options_.signal == SimulatedLtcSignal::kLtc       ? "LTC"
                                : options_.signal == SimulatedLtcSignal::kSilence ? "silence"
                                                                                  : "noise";
  return "sim:" + std::string(what) + "@" + std::to_string(options_.sample_rate);
}

AudioStatus SimulatedLtcAudio::read(AudioBlock& block, std::chrono::milliseconds timeout) {
  const auto frames = static_cast<std::int64_t>(options_.block_frames);
  if (start_ns_.load(std::memory_order_relaxed) == 0) start_ns_.store(monotonic_ns(), std::memory_order_release);
  const std::int64_t start_ns = start_ns_.load(std::memory_order_relaxed);
  const auto sample_ns = [&](std::int64_t sample) { return start_ns + sample * 1'000'000'000 / options_.sample_rate; };
  const std::int64_t first = blocks_ * frames;
  const std::int64_t due = sample_ns(first + frames);
  if (due - monotonic_ns() > std::chrono::nanoseconds(timeout).count()) {
    std::this_thread::sleep_for(timeout);
    return AudioStatus::kTimeout;
  }
  // steady_clock is CLOCK_MONOTONIC.
  std::this_thread::sleep_until(std::chrono::steady_clock::time_point(std::chrono::nanoseconds(due)));

  std::uniform_real_distribution<float> noise(-0.3f, 0.3f);
  for (std::size_t i = 0; i < static_cast<std::size_t>(frames); ++i) {
    // The generator runs whatever the signal, so a signal switched back on resumes in step.
    if (pending_begin_ == pending_.size()) {
      const std::span<const float> next = generator_.next_frame();
      pending_.assign(next.begin(), next.end());
      pending_begin_ = 0;
    }
    const float ltc = pending_[pending_begin_++];
    float& out = block.samples[i];
    switch (options_.signal) {
      case SimulatedLtcSignal::kLtc: out = ltc; break;
      case SimulatedLtcSignal::kSilence: out = 0; break;
      case SimulatedLtcSignal::kNoise: out = noise(noise_); break;
    }
  }
  block.frames = static_cast<int>(frames);
  block.sample_rate = options_.sample_rate;
  block.capture_time_ns = sample_ns(first);
  block.position = static_cast<std::uint64_t>(first);
  block.media_time_s = static_cast<double>(first) / options_.sample_rate;
  ++blocks_;
  return AudioStatus::kBlock;
}

}  // namespace lipdrive
