// The audio track of a recording, decoded whole with FFmpeg's libraries (libavformat,
// libavcodec, libswresample): the simulated microphone of a replayed clip, and the sound the
// voice model is trained and evaluated on.
#pragma once

#include "drivers/audio_source.hpp"

#include <filesystem>
#include <vector>

namespace lipdrive {

struct DecodedAudio {
  std::vector<float> samples;  // mono: the mean of the track's channels, [-1, 1]
  int sample_rate = 0;         // as asked for (resampled)
  int source_rate = 0;         // the track's own
  /// Where samples[0] lies on the recording's timeline, whose 0 is its first video frame (the
  /// audio stream's start minus the video stream's; 0 without a video stream).
  double start_s = 0;
};

/// Decodes the first audio track of `file` and resamples it to `sample_rate`. Throws
/// AudioSourceError naming the file: it cannot be opened or read, it has no audio track, or
/// the track cannot be decoded.
DecodedAudio decode_audio(const std::filesystem::path& file, int sample_rate);

}  // namespace lipdrive
