// The timecode a frame is stamped with ([timecode], docs/timecode.md): the time of day of the
// system clock at a configured rate, or SMPTE LTC decoded from an audio input.
//
// Thread model: frame_at() is called on the processing thread for every frame and only reads
// (lock-free, no allocation). The LTC source owns its decoder and an AudioListener
// (firmware_app/daemon/audio_listener.hpp) whose thread feeds it and publishes the newest
// decoded frame and its start time through a seqlock; the Daemon declares the source before
// the pipeline that reads it.
#pragma once

#include "core/timecode.hpp"
#include "drivers/audio_source.hpp"
#include "drivers/ltc_decoder.hpp"
#include "firmware_app/daemon/audio_listener.hpp"
#include "firmware_app/daemon/latest_frame.hpp"

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace lipdrive {

class TimecodeSource {
 public:
  explicit TimecodeSource(TimecodeRate rate) : rate_(rate) {}
  virtual ~TimecodeSource() = default;
  TimecodeSource(const TimecodeSource&) = delete;
  TimecodeSource& operator=(const TimecodeSource&) = delete;

  /// Any thread: the frame number (core/timecode.hpp) of the moment `capture_time_ns`
  /// (CLOCK_MONOTONIC); nullopt when the source cannot tell (LTC absent).
  virtual std::optional<std::int32_t> frame_at(std::int64_t capture_time_ns) const = 0;
  /// Main thread, for the status line: why frames go unstamped or may be wrong; "" when fine.
  virtual std::string problem() const { return {}; }
  virtual std::string describe() const = 0;
  TimecodeRate rate() const { return rate_; }

 private:
  TimecodeRate rate_;
};

/// Time of day of the wall clock (drivers/clock.hpp wall_time_ns), in the local time zone of
/// the moment the source was made: frame = floor(seconds since local midnight · fps). At
/// 29.97 drop-frame the labels keep to the clock within the 3.6 ms per hour drop-frame allows.
class ClockTimecode : public TimecodeSource {
 public:
  explicit ClockTimecode(TimecodeRate rate);
  std::optional<std::int32_t> frame_at(std::int64_t capture_time_ns) const override;
  std::string describe() const override;

 private:
  std::int64_t utc_offset_ns_;  // local time - UTC, taken once
};

/// LTC on an audio input: frames decoded by libltc, stamped with the capture time of their
/// first sample; a capture time maps to the newest decoded frame plus the frames since its
/// start. A frame counts once it follows its predecessor (two consecutive labels), so one
/// garbled frame never stamps anything. No good frame for 0.5 s: LTC is absent and frames go
/// unstamped.
class LtcTimecode : public TimecodeSource {
 public:
  /// Takes the audio input; starts reading it (at the frame path's `realtime_priority`,
  /// AudioListener). Throws std::runtime_error when libltc cannot make its decoder.
  LtcTimecode(std::unique_ptr<AudioSource> input, TimecodeRate rate, int realtime_priority = 0);

  std::optional<std::int32_t> frame_at(std::int64_t capture_time_ns) const override;
  std::string problem() const override;
  std::string describe() const override;

  std::uint64_t frames_decoded() const { return decoded_.load(std::memory_order_relaxed); }
  /// Frames that were not a label at this rate, had the wrong drop-frame flag, or did not
  /// follow their predecessor.
  std::uint64_t frames_rejected() const { return rejected_.load(std::memory_order_relaxed); }

 private:
  struct Anchor {
    std::int32_t frame = 0;
    std::int64_t start_ns = 0;  // CLOCK_MONOTONIC of its first sample
  };

  void hear(const AudioBlock& block);
  void take(const LtcFrame& frame);

  LtcDecoder decoder_;                // the listener's thread's
  std::optional<std::int32_t> last_;  // the listener's thread's: the previous decoded label
  Published<Anchor> anchor_;
  std::atomic<std::uint64_t> decoded_{0}, rejected_{0};
  std::atomic<std::int64_t> last_rejected_ns_{0};
  AudioListener listener_;  // last: its thread uses the members above
};

}  // namespace lipdrive
