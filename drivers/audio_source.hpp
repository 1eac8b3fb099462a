// The one interface every microphone input implements: ALSA capture and the simulated
// audio of a replayed clip (DESIGN.md 2, AudioSource).
//
// Thread model: an AudioSource is owned and called by exactly one thread (the daemon's audio
// thread, or a test).
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace lipdrive {

/// The most sample frames one block carries (a 64 ms period at 16 kHz).
inline constexpr int kMaxAudioBlockFrames = 1024;

/// One block of mono samples, fixed-size so that it can be reused without allocating.
struct AudioBlock {
  std::array<float, kMaxAudioBlockFrames> samples{};  // [-1, 1], the configured channel
  int frames = 0;                                     // valid samples
  int sample_rate = 0;                                // frames per second
  std::int64_t capture_time_ns = 0;                   // CLOCK_MONOTONIC when samples[0] was captured
  std::uint64_t position = 0;                         // index of samples[0] in the source's stream of samples;
                                                      // a jump larger than the previous block says samples were lost
  double media_time_s = 0;  // samples[0]'s place in the recording (replay) or since start (live)
};

/// A source that cannot be opened at all (unknown device, unsupported rate, a clip without
/// an audio track); the message names the device or file and the reason.
class AudioSourceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class AudioStatus {
  kBlock,         // `block` holds new samples
  kTimeout,       // nothing arrived within the timeout; try again
  kEndOfStream,   // a recording ended (never for live capture or a looping replay)
  kDisconnected,  // the device went away; read() keeps trying to reopen it
};

class AudioSource {
 public:
  virtual ~AudioSource() = default;
  virtual AudioStatus read(AudioBlock& block, std::chrono::milliseconds timeout) = 0;
  virtual int sample_rate() const = 0;
  /// Human-readable name for logs and the status line ("alsa:hw:1,0", "sim:clip.mpg").
  virtual std::string describe() const = 0;
};

}  // namespace lipdrive
