#include "drivers/alsa_capture.hpp"

#include "core/audio_rates.hpp"
#include "drivers/clock.hpp"

#include <alsa/asoundlib.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <mutex>
#include <thread>

namespace lipdrive {
namespace {

constexpr std::int64_t kNsPerSecond = 1'000'000'000;
// Overruns come in bursts when the machine is loaded: one log line a second at most.
constexpr std::int64_t kXrunLogIntervalNs = kNsPerSecond;

// alsa-lib prints its own errors on stderr; they go to the log at debug level instead, the
// caller's message says what went wrong.
void alsa_error_to_log(const char* file, int line, const char* function, int error, const char* format, ...) {
  if (!spdlog::should_log(spdlog::level::debug)) return;
  char text[256];
  va_list args;
  va_start(args, format);
  std::vsnprintf(text, sizeof text, format, args);
  va_end(args);
  spdlog::debug("alsa-lib {}:{} ({}): {}{}", file, line, function, text,
                error != 0 ? fmt::format(": {}", snd_strerror(error)) : std::string());
}

class AlsaLibPcm final : public AlsaPcm {
 public:
  ~AlsaLibPcm() override { close(); }

  std::string open(const AlsaCaptureOptions& options) override {
    close();
    if (const int e = snd_pcm_open(&pcm_, options.device.c_str(), SND_PCM_STREAM_CAPTURE, SND_PCM_NONBLOCK); e < 0) {
      pcm_ = nullptr;
      return fmt::format("cannot open the capture device: {}", snd_strerror(e));
    }
    std::string problem = configure(options);
    if (!problem.empty()) close();
    return problem;
  }

  void close() override {
    if (pcm_) snd_pcm_close(pcm_);
    pcm_ = nullptr;
  }

  int wait(int timeout_ms) override { return snd_pcm_wait(pcm_, timeout_ms); }

  long read(std::int16_t* interleaved, long frames) override {
    return static_cast<long>(snd_pcm_readi(pcm_, interleaved, static_cast<snd_pcm_uframes_t>(frames)));
  }

  bool timestamp(long& available, std::int64_t& time_ns) override {
    snd_pcm_uframes_t avail = 0;
    snd_htimestamp_t stamp{};
    if (snd_pcm_htimestamp(pcm_, &avail, &stamp) < 0 || (stamp.tv_sec == 0 && stamp.tv_nsec == 0)) return false;
    available = static_cast<long>(avail);
    time_ns = std::int64_t{stamp.tv_sec} * kNsPerSecond + stamp.tv_nsec;
    return true;
  }

  int restart() override {
    // A suspended stream may resume where it was; otherwise it starts afresh.
    if (snd_pcm_state(pcm_) == SND_PCM_STATE_SUSPENDED && snd_pcm_resume(pcm_) == 0) return 0;
    if (const int e = snd_pcm_prepare(pcm_); e < 0) return e;
    return snd_pcm_start(pcm_);
  }

 private:
  std::string configure(const AlsaCaptureOptions& o) {
    snd_pcm_hw_params_t* hw = nullptr;
    snd_pcm_hw_params_alloca(&hw);
    snd_pcm_hw_params_any(pcm_, hw);
    const auto failed = [](const char* what, int e) { return fmt::format("{}: {}", what, snd_strerror(e)); };
    if (const int e = snd_pcm_hw_params_set_access(pcm_, hw, SND_PCM_ACCESS_RW_INTERLEAVED); e < 0)
      return failed("interleaved access", e);
    if (const int e = snd_pcm_hw_params_set_format(pcm_, hw, SND_PCM_FORMAT_S16); e < 0)
      return failed("signed 16-bit samples not supported", e);
    if (const int e = snd_pcm_hw_params_set_channels(pcm_, hw, static_cast<unsigned>(o.channels)); e < 0) {
      unsigned lo = 0, hi = 0;
      snd_pcm_hw_params_get_channels_min(hw, &lo);
      snd_pcm_hw_params_get_channels_max(hw, &hi);
      return fmt::format("{} channels not supported (the device offers {}..{})", o.channels, lo, hi);
    }
    if (const int e = snd_pcm_hw_params_set_rate(pcm_, hw, static_cast<unsigned>(o.sample_rate), 0); e < 0) {
      unsigned lo = 0, hi = 0;
      snd_pcm_hw_params_get_rate_min(hw, &lo, nullptr);
      snd_pcm_hw_params_get_rate_max(hw, &hi, nullptr);
      return fmt::format("sample rate {} Hz not supported (the device offers {}..{} Hz; a plughw: device resamples)",
                         o.sample_rate, lo, hi);
    }
    snd_pcm_uframes_t period = static_cast<snd_pcm_uframes_t>(o.period_frames);
    if (const int e = snd_pcm_hw_params_set_period_size(pcm_, hw, period, 0); e < 0)
      return fmt::format("a period of {} samples is not supported: {}", o.period_frames, snd_strerror(e));
    snd_pcm_uframes_t buffer = period * static_cast<snd_pcm_uframes_t>(o.periods);
    if (const int e = snd_pcm_hw_params_set_buffer_size_near(pcm_, hw, &buffer); e < 0) return failed("buffer size", e);
    if (const int e = snd_pcm_hw_params(pcm_, hw); e < 0) return failed("hardware parameters", e);

    snd_pcm_sw_params_t* sw = nullptr;
    snd_pcm_sw_params_alloca(&sw);
    snd_pcm_sw_params_current(pcm_, sw);
    snd_pcm_sw_params_set_avail_min(pcm_, sw, period);
    // The driver stamps its position updates on the clock the camera frames use.
    snd_pcm_sw_params_set_tstamp_mode(pcm_, sw, SND_PCM_TSTAMP_ENABLE);
    snd_pcm_sw_params_set_tstamp_type(pcm_, sw, SND_PCM_TSTAMP_TYPE_MONOTONIC);
    if (const int e = snd_pcm_sw_params(pcm_, sw); e < 0) return failed("software parameters", e);
    if (const int e = snd_pcm_start(pcm_); e < 0) return failed("start", e);
    return {};
  }

  snd_pcm_t* pcm_ = nullptr;
};

bool is_disconnect(long error) {
  return error == -ENODEV || error == -ENXIO || error == -EIO || error == -EBADFD || error == -ENOENT;
}

int milliseconds_until(std::chrono::steady_clock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
  return static_cast<int>(std::max<std::int64_t>(left.count(), 0));
}

}  // namespace

std::unique_ptr<AlsaPcm> make_alsa_pcm() {
  static std::once_flag quiet;
  std::call_once(quiet, [] { snd_lib_error_set_handler(&alsa_error_to_log); });
  return std::make_unique<AlsaLibPcm>();
}

AlsaCapture::AlsaCapture(AlsaCaptureOptions options, std::unique_ptr<AlsaPcm> pcm)
    : options_(std::move(options)), pcm_(std::move(pcm)), reopen_backoff_(options_.reopen_first, options_.reopen_max) {
  const AlsaCaptureOptions& o = options_;
  if (o.channels < 1 || o.channels > 8 || o.channel < 0 || o.channel >= o.channels)
    throw AudioSourceError(
        fmt::format("{}: channel {} of {} channels: out of range", describe(), o.channel, o.channels));
  if (o.sample_rate < kMinAudioSampleRate || o.sample_rate > kMaxAudioSampleRate || o.period_frames < 16 ||
      o.period_frames > kMaxAudioBlockFrames || o.periods < 2)
    throw AudioSourceError(
        fmt::format("{}: rate {} Hz or period {} samples out of range", describe(), o.sample_rate, o.period_frames));
  std::string problem = pcm_->open(o);
  if (problem.empty()) {
    open_ = true;
    return;
  }
  if (o.must_open) throw AudioSourceError(fmt::format("{}: {}", describe(), problem));
  reopen_error_ = std::move(problem);
  after_gap_ = true;
  next_reopen_ = Clock::now() + reopen_backoff_.failed();
}

AlsaCapture::~AlsaCapture() {
  if (open_) pcm_->close();
}

AlsaCounters AlsaCapture::counters() const {
  return {blocks_.load(std::memory_order_relaxed), xruns_.load(std::memory_order_relaxed),
          samples_lost_.load(std::memory_order_relaxed), disconnects_.load(std::memory_order_relaxed),
          reconnects_.load(std::memory_order_relaxed)};
}

AudioStatus AlsaCapture::read(AudioBlock& block, std::chrono::milliseconds timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  if (!open_ && !reopen_before(deadline)) return AudioStatus::kDisconnected;
  const int ready = pcm_->wait(milliseconds_until(deadline));
  if (ready < 0) return fail(ready, "wait");
  if (ready == 0) return AudioStatus::kTimeout;
  const long frames = pcm_->read(interleaved_.data(), options_.period_frames);
  if (frames < 0) return fail(frames, "read");
  if (frames == 0) return AudioStatus::kTimeout;

  const std::int64_t first_ns = first_sample_time_ns(frames);
  const double rate = options_.sample_rate;
  if (after_gap_ && expected_next_ns_ != 0) {
    // The samples the overrun or the outage lost, on the driver's clock.
    const auto lost = std::llround(static_cast<double>(first_ns - expected_next_ns_) * rate / 1e9);
    if (lost > 0) {
      position_ += static_cast<std::uint64_t>(lost);
      samples_lost_.fetch_add(static_cast<std::uint64_t>(lost), std::memory_order_relaxed);
    }
  }
  after_gap_ = false;
  const auto channels = static_cast<std::size_t>(options_.channels);
  const auto channel = static_cast<std::size_t>(options_.channel);
  for (std::size_t i = 0; i < static_cast<std::size_t>(frames); ++i)
    block.samples[i] = static_cast<float>(interleaved_[i * channels + channel]) / 32768.0f;
  block.frames = static_cast<int>(frames);
  block.sample_rate = options_.sample_rate;
  block.capture_time_ns = first_ns;
  block.position = position_;
  block.media_time_s = static_cast<double>(position_) / rate;
  position_ += static_cast<std::uint64_t>(frames);
  expected_next_ns_ = first_ns + std::llround(static_cast<double>(frames) * 1e9 / rate);
  blocks_.fetch_add(1, std::memory_order_relaxed);
  return AudioStatus::kBlock;
}

std::int64_t AlsaCapture::first_sample_time_ns(long frames) {
  const double ns_per_sample = 1e9 / options_.sample_rate;
  long available = 0;
  std::int64_t stamp_ns = 0;
  if (pcm_->timestamp(available, stamp_ns))
    return stamp_ns - std::llround(static_cast<double>(available + frames) * ns_per_sample);
  if (!said_no_timestamps_) {
    said_no_timestamps_ = true;
    spdlog::warn("{}: the driver gives no timestamps; blocks are stamped when they are read", describe());
  }
  return monotonic_ns() - std::llround(static_cast<double>(frames) * ns_per_sample);
}

AudioStatus AlsaCapture::fail(long error, const char* call) {
  if (error == -EAGAIN || error == -EINTR) return AudioStatus::kTimeout;
  if (error == -EPIPE || error == -ESTRPIPE) {
    const std::uint64_t count = xruns_.fetch_add(1, std::memory_order_relaxed) + 1;
    const std::int64_t now = monotonic_ns();
    if (now - last_xrun_log_ns_ >= kXrunLogIntervalNs) {
      last_xrun_log_ns_ = now;
      spdlog::warn("{}: {} ({} so far); the capture restarts", describe(),
                   error == -EPIPE ? "overrun: samples were lost" : "suspended", count);
    }
    after_gap_ = true;
    if (const int e = pcm_->restart(); e < 0) return fail(is_disconnect(e) ? e : -EIO, "restart");
    return AudioStatus::kTimeout;
  }
  spdlog::warn("{}: {} failed: {}; the device is reopened", describe(), call, snd_strerror(static_cast<int>(error)));
  disconnect();
  return AudioStatus::kDisconnected;
}

void AlsaCapture::disconnect() {
  pcm_->close();
  open_ = false;
  after_gap_ = true;
  disconnects_.fetch_add(1, std::memory_order_relaxed);
  reopen_backoff_.succeeded();  // the stream was up: retries start again at the first delay
  next_reopen_ = Clock::now() + reopen_backoff_.failed();
}

bool AlsaCapture::reopen_before(Clock::time_point deadline) {
  if (next_reopen_ > deadline) {
    // Waiting out the timeout keeps a caller that loops on read() from spinning.
    std::this_thread::sleep_until(deadline);
    return false;
  }
  std::this_thread::sleep_until(next_reopen_);
  if (std::string problem = pcm_->open(options_); !problem.empty()) {
    if (problem != reopen_error_) spdlog::warn("{}: {}", describe(), problem);
    reopen_error_ = std::move(problem);
    next_reopen_ = Clock::now() + reopen_backoff_.failed();
    return false;
  }
  reopen_backoff_.succeeded();
  reopen_error_.clear();
  open_ = true;
  reconnects_.fetch_add(1, std::memory_order_relaxed);
  spdlog::info("{}: capturing again", describe());
  return true;
}

}  // namespace lipdrive
