// A performer's recordings as voice-model material (core/voice_training.hpp): a clip with
// sound, whose video is tracked here with the daemon's per-frame processor (a GRID word
// alignment beside it, same name, .align, marks its speech frames), or a take the daemon
// recorded (NAME.csv) with its sound beside it (NAME.wav, firmware_app/daemon/take_sound.hpp),
// whose rows hold what the video tracked live.
#pragma once

#include "core/voice_training.hpp"
#include "firmware_app/daemon/frame_processor.hpp"

#include <filesystem>

namespace lipdrive {

/// A clip with sound, or a take (.csv) with its sound, resampled to `sample_rate`. Throws
/// CommandError naming the file: kExitNoInput when it (or a take's sound) is missing,
/// kExitDataError when it has no sound (no audio track, or an image or a folder), a take's
/// table cannot be read, a row's capture_time_ns is missing or earlier than the row before's,
/// a take's rows run past the end of its sound (naming the first such row), or it has no
/// tracked frame.
VoiceRecording load_voice_recording(const std::filesystem::path& input, int sample_rate, FrameProcessor& processor);

}  // namespace lipdrive
