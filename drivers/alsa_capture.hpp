// ALSA capture of the performer's microphone (alsa-lib) as an AudioSource.
//
// Every block is stamped on CLOCK_MONOTONIC from the driver's own timestamp of its position
// (snd_pcm_htimestamp, with the stream's timestamp type set to monotonic), not from when the
// reading thread woke up: the first sample of a block read just now was captured
// (available + block) samples before the driver's timestamp. A driver that gives no timestamp
// falls back to the wake-up time, said once in the log.
//
// Overruns (xruns: the reader fell behind and the ring overflowed) are counted and logged,
// never fatal: the stream is restarted, and the samples lost show as a jump of
// AudioBlock::position worked out from the timestamps. A device that goes away (ENODEV, EIO,
// EBADFD) is released at once, read() reports kDisconnected and reopens it with the shared
// back-off (core/backoff.hpp), never waiting longer than its timeout.
//
// alsa-lib sits behind AlsaPcm, a seam: tests put a fake device there (there is no sound card
// on a build machine).
//
// Thread model: one thread owns an AlsaCapture and makes every call on it; counters() may be
// read from any thread.
#pragma once

#include "core/backoff.hpp"
#include "drivers/audio_source.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

namespace lipdrive {

struct AlsaCaptureOptions {
  std::string device = "default";  // an ALSA PCM name: "default", "hw:1,0", "plughw:CARD=USB,DEV=0"
  int sample_rate = 16000;         // must be exact: a device that cannot (hw:) is an error; plughw: resamples
  int channels = 1;                // channels opened on the device, 1..8
  int channel = 0;                 // the one delivered, 0-based, < channels
  int period_frames = 160;         // samples per block (10 ms at 16 kHz), ≤ kMaxAudioBlockFrames
  int periods = 4;                 // the driver's ring, in periods
  std::chrono::milliseconds reopen_first{100};
  std::chrono::milliseconds reopen_max{5000};
  /// false: a device that cannot be opened at construction (not plugged in yet) is not an
  /// error; read() reports kDisconnected and keeps trying with the back-off.
  bool must_open = true;
};

/// The alsa-lib calls one capture stream needs (the seam the tests fake). Negative results
/// are negative errno values, as alsa-lib returns them.
class AlsaPcm {
 public:
  virtual ~AlsaPcm() = default;
  /// Opens `options.device` for capture (non-blocking), interleaved signed 16-bit at exactly
  /// the rate, channel count and period asked for, timestamps on CLOCK_MONOTONIC, and starts
  /// it. Returns "" or why it cannot (alsa-lib's message).
  virtual std::string open(const AlsaCaptureOptions& options) = 0;
  virtual void close() = 0;
  /// snd_pcm_wait: 1 when samples are ready, 0 on timeout, else a negative errno.
  virtual int wait(int timeout_ms) = 0;
  /// snd_pcm_readi into `interleaved` (frames · channels values): frames read or a negative errno
  /// (-EAGAIN nothing yet, -EPIPE overrun, -ESTRPIPE suspended, -ENODEV gone).
  virtual long read(std::int16_t* interleaved, long frames) = 0;
  /// snd_pcm_htimestamp: the samples available and the CLOCK_MONOTONIC time (ns) the driver
  /// took them at; false when the driver gives no timestamp.
  virtual bool timestamp(long& available, std::int64_t& time_ns) = 0;
  /// After an overrun or a suspend: snd_pcm_prepare and snd_pcm_start; 0 or a negative errno.
  virtual int restart() = 0;
};

/// The real one.
std::unique_ptr<AlsaPcm> make_alsa_pcm();

struct AlsaCounters {
  std::uint64_t blocks = 0;        // blocks delivered
  std::uint64_t xruns = 0;         // overruns (and suspends) recovered from
  std::uint64_t samples_lost = 0;  // by the overruns, from the timestamps
  std::uint64_t disconnects = 0;   // times the device went away
  std::uint64_t reconnects = 0;    // times it was reopened
};

class AlsaCapture final : public AudioSource {
 public:
  /// Opens the device. Throws AudioSourceError "alsa:DEVICE: reason" when the options are out of
  /// range, or when it cannot be opened (unknown device, rate or channel count not supported)
  /// and options.must_open.
  explicit AlsaCapture(AlsaCaptureOptions options, std::unique_ptr<AlsaPcm> pcm = make_alsa_pcm());
  ~AlsaCapture() override;
  AlsaCapture(const AlsaCapture&) = delete;
  AlsaCapture& operator=(const AlsaCapture&) = delete;

  AudioStatus read(AudioBlock& block, std::chrono::milliseconds timeout) override;
  int sample_rate() const override { return options_.sample_rate; }
  std::string describe() const override { return "alsa:" + options_.device; }

  AlsaCounters counters() const;
  bool is_open() const { return open_; }
  /// Why the last (re)open failed; "" while the device delivers.
  const std::string& reopen_error() const { return reopen_error_; }

 private:
  using Clock = std::chrono::steady_clock;

  AudioStatus fail(long error, const char* call);
  void disconnect();
  bool reopen_before(Clock::time_point deadline);
  std::int64_t first_sample_time_ns(long frames);

  AlsaCaptureOptions options_;
  std::unique_ptr<AlsaPcm> pcm_;
  bool open_ = false;
  Backoff reopen_backoff_;
  Clock::time_point next_reopen_{};
  std::string reopen_error_;
  std::array<std::int16_t, kMaxAudioBlockFrames * 8> interleaved_{};

  // The stream's sample clock: the position of the next sample, and where the previous
  // block ended in time (to see what an overrun lost).
  std::uint64_t position_ = 0;
  std::int64_t expected_next_ns_ = 0;
  bool after_gap_ = false;  // an overrun or a reopen: the next block may start later than expected
  bool said_no_timestamps_ = false;
  std::int64_t last_xrun_log_ns_ = 0;

  std::atomic<std::uint64_t> blocks_{0}, xruns_{0}, samples_lost_{0}, disconnects_{0}, reconnects_{0};
};

}  // namespace lipdrive
