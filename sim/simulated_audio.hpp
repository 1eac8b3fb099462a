// The simulated microphone: the audio track of the replayed clip (decoded with FFmpeg,
// drivers/audio_file.hpp), played in real time as a sound card delivers it and in step with
// the simulated camera replaying the same clip (both keep to one ReplayClock), so that CI and a
// bench without hardware run the whole voice path.
#pragma once

#include "drivers/audio_source.hpp"
#include "sim/replay_clock.hpp"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace lipdrive {

struct SimulatedAudioOptions {
  std::filesystem::path clip;  // a recording with an audio track
  int sample_rate = 16000;     // the track is resampled to this
  int block_frames = 160;      // samples per block (10 ms at 16 kHz), at most kMaxAudioBlockFrames
  /// > 0: the recording restarts every loop_s seconds, as the looping video replay does
  /// (SimulatedCamera::duration_s()); 0: it plays once, then kEndOfStream.
  double loop_s = 0;
  /// Fault injection: `disconnect_after_s` seconds into the replay the microphone goes away
  /// for `reconnect` (once), and the samples of that time are lost. 0 = off.
  double disconnect_after_s = 0;
  std::chrono::milliseconds reconnect{0};
};

class SimulatedClipAudio final : public AudioSource {
 public:
  /// Decodes the clip's audio track. Throws AudioSourceError naming the clip when it has none
  /// or it cannot be decoded, std::invalid_argument for options out of range. `clock` (not
  /// owned, outlives this) is the replay's timeline shared with the camera; without one the
  /// first read() starts a timeline of its own.
  explicit SimulatedClipAudio(SimulatedAudioOptions options, ReplayClock* clock = nullptr);

  /// Block n holds the samples of [n·B, (n+1)·B) on the timeline, stamped at its start and
  /// returned once its last sample is due; the clip's sound where it has some, else silence.
  AudioStatus read(AudioBlock& block, std::chrono::milliseconds timeout) override;
  int sample_rate() const override { return options_.sample_rate; }
  std::string describe() const override { return "sim:" + options_.clip.string(); }

 private:
  float sample_at(std::int64_t timeline_sample) const;

  SimulatedAudioOptions options_;
  ReplayClock own_clock_;
  ReplayClock* clock_;
  std::vector<float> samples_;
  std::int64_t track_start_ = 0;   // timeline sample of samples_[0] within one pass
  std::int64_t loop_samples_ = 0;  // 0: no looping
  std::int64_t next_block_ = 0;
  bool started_ = false;
  std::int64_t outage_begin_ = 0, outage_end_ = 0;  // timeline samples; equal: none
};

}  // namespace lipdrive
