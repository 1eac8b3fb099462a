// Sound files through FFmpeg's libraries (libavformat, libavcodec, libswresample): the audio
// track of a recording decoded whole (the simulated microphone of a replayed clip, the sound
// the voice model is trained and evaluated on), and the WAV file a take's sound is written to.
#pragma once

#include "core/audio_rates.hpp"
#include "drivers/audio_source.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

namespace lipdrive {

struct DecodedAudio {
  std::vector<float> samples;  // mono: the mean of the track's channels, [-1, 1]
  int sample_rate = 0;         // as asked for (resampled)
  int source_rate = 0;         // the track's own
  /// Where samples[0] lies on the recording's timeline, whose 0 is its first video frame (the
  /// audio stream's start minus the video stream's; 0 without a video stream).
  double start_s = 0;
  int damaged_packets = 0;  // skipped (their time is silence)
};

/// Decodes the first audio track of `file` and resamples it to `sample_rate`, following a
/// track whose channels, sample format or rate change on the way; damaged packets are skipped
/// and counted (a warning in the log). Throws AudioSourceError naming the file: it cannot be
/// opened or read, it has no audio track, the track cannot be decoded, or its sample rate is
/// below kMinAudioSampleRate (checked before any sound is decoded, and again where it changes:
/// resampling such a track would cost memory out of all proportion to the file, a 400 KB WAV at
/// 10 Hz being 20,000 s long, 1.3 GB of samples at 16 kHz).
DecodedAudio decode_audio(const std::filesystem::path& file, int sample_rate);

/// A mono 16-bit PCM WAV file written block by block through FFmpeg's WAV muxer. The sizes in
/// its header are set when it is closed; a file cut short (a crash) still decodes up to its
/// last block. Thread model: one thread makes every call.
class WavWriter {
 public:
  /// Creates (or replaces) `file`. Throws AudioSourceError naming the file when it cannot.
  WavWriter(const std::filesystem::path& file, int sample_rate);
  /// Closes the file; errors are not reported here (call close() to see them).
  ~WavWriter();
  WavWriter(const WavWriter&) = delete;
  WavWriter& operator=(const WavWriter&) = delete;

  /// Appends samples in [-1, 1] (clipped). Throws AudioSourceError on a write error.
  void write(std::span<const float> samples);
  /// Appends `count` samples of silence.
  void write_silence(std::int64_t count);
  /// Samples written so far.
  std::int64_t samples() const { return samples_; }
  /// Sets the header's sizes and closes the file. Throws AudioSourceError on a write error.
  void close();

 private:
  void write_pcm(const std::int16_t* pcm, int count);

  struct Muxer;
  std::unique_ptr<Muxer> muxer_;
  std::string name_;
  std::int64_t samples_ = 0;
};

}  // namespace lipdrive
