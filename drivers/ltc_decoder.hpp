// SMPTE linear timecode (LTC) decoded from an audio channel (libltc).
//
// Mono sample blocks from any AudioSource (drivers/audio_source.hpp: ALSA capture, the
// simulated inputs) are fed in; every LTC frame that completes comes out with its label and
// the CLOCK_MONOTONIC time its first sample was captured, taken from the block timestamps and
// the sample position libltc reports (to within a sample or two).
//
// Thread model: one owner thread calls write() and read(). Neither allocates.
#pragma once

#include <cstdint>
#include <span>

struct LTCDecoder;

namespace lipdrive {

struct LtcFrame {
  int hours = 0, minutes = 0, seconds = 0, frames = 0;
  bool drop_frame = false;         // the frame's drop-frame flag (29.97 fps)
  bool reverse = false;            // the tape ran backwards
  std::int64_t start_time_ns = 0;  // CLOCK_MONOTONIC of the frame's first sample
  double volume_dbfs = 0;          // signal level of the frame
};

class LtcDecoder {
 public:
  /// `expected_fps` sets libltc's first guess of samples per frame (it follows the actual
  /// speed from there). Throws std::runtime_error when libltc cannot allocate its decoder.
  LtcDecoder(int sample_rate, double expected_fps);
  ~LtcDecoder();
  LtcDecoder(const LtcDecoder&) = delete;
  LtcDecoder& operator=(const LtcDecoder&) = delete;

  /// Decodes a block of mono samples in [-1, 1] whose first sample was captured at
  /// `first_sample_time_ns` (CLOCK_MONOTONIC); blocks follow each other without gaps.
  void write(std::span<const float> samples, int sample_rate, std::int64_t first_sample_time_ns);
  /// The oldest decoded frame not read yet; false when there is none.
  bool read(LtcFrame& frame);

 private:
  LTCDecoder* decoder_ = nullptr;
  std::int64_t position_ = 0;        // stream position of the next sample
  std::int64_t block_position_ = 0;  // of the last block's first sample
  std::int64_t block_time_ns_ = 0;   // and its capture time
  int sample_rate_ = 48000;
};

}  // namespace lipdrive
