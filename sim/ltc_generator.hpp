// SMPTE LTC audio as a timecode generator puts it on a line (libltc's encoder), and a
// simulated audio input that plays it in real time: the test signal of the LTC decoder and
// the daemon's LTC source when no sound card carries one.
#pragma once

#include "core/timecode.hpp"
#include "drivers/audio_source.hpp"

#include <atomic>
#include <cstdint>
#include <random>
#include <span>
#include <string>
#include <vector>

struct LTCEncoder;

namespace lipdrive {

class LtcGenerator {
 public:
  /// Frames from `start_frame` on (frame numbers of core/timecode.hpp), at `level_dbfs`.
  /// Throws std::runtime_error when libltc cannot create its encoder.
  LtcGenerator(int sample_rate, TimecodeRate rate, std::int32_t start_frame, double level_dbfs = -10);
  ~LtcGenerator();
  LtcGenerator(const LtcGenerator&) = delete;
  LtcGenerator& operator=(const LtcGenerator&) = delete;

  /// The number of the frame next_frame() produces.
  std::int32_t frame() const { return frame_; }
  /// The samples of the next frame, in [-1, 1]; valid until the next call. Their count
  /// follows the rate exactly over time (1601 or 1602 per frame at 48 kHz and 29.97 fps).
  std::span<const float> next_frame();

 private:
  LTCEncoder* encoder_ = nullptr;
  TimecodeRate rate_;
  std::int32_t frame_;
  std::vector<float> samples_;
};

/// What the simulated input carries.
enum class SimulatedLtcSignal { kLtc, kSilence, kNoise };

struct SimulatedLtcOptions {
  int sample_rate = 48000;
  TimecodeRate rate = TimecodeRate::k25;
  Timecode start{};  // the first frame's label
  SimulatedLtcSignal signal = SimulatedLtcSignal::kLtc;
  int block_frames = 480;  // samples per block (10 ms at 48 kHz), at most kMaxAudioBlockFrames
};

/// Plays generated LTC in real time as a sound card delivers it: the first read() starts
/// the sample clock; block n holds samples [n·B, (n+1)·B) stamped at start + n·B / rate and
/// is returned once its last sample is due. Throws std::invalid_argument when `start` is
/// not a label of `rate` or the options are out of range.
class SimulatedLtcAudio final : public AudioSource {
 public:
  explicit SimulatedLtcAudio(SimulatedLtcOptions options);

  AudioStatus read(AudioBlock& block, std::chrono::milliseconds timeout) override;
  int sample_rate() const override { return options_.sample_rate; }
  std::string describe() const override;

  /// CLOCK_MONOTONIC when the first frame (options.start) began; 0 before the first read().
  /// Any thread.
  std::int64_t start_time_ns() const { return start_ns_.load(std::memory_order_acquire); }

 private:
  SimulatedLtcOptions options_;
  LtcGenerator generator_;
  std::vector<float> pending_;  // generated samples not yet in a block (mono)
  std::size_t pending_begin_ = 0;
  std::atomic<std::int64_t> start_ns_{0};
  std::int64_t blocks_ = 0;
  std::minstd_rand noise_{12345};
};

}  // namespace lipdrive
