// A performer's recordings as voice-model material (core/voice_training.hpp): a clip with
// sound, whose video is tracked here with the daemon's per-frame processor. A GRID word
// alignment beside a clip (same name, .align) marks its speech frames.
#pragma once

#include "core/voice_training.hpp"
#include "firmware_app/daemon/frame_processor.hpp"

#include <filesystem>

namespace lipdrive {

/// A clip with sound, resampled to `sample_rate`. Throws CommandError naming the file:
/// kExitNoInput when it is missing, kExitDataError when it has no sound (no audio track, or an
/// image or a folder) or no tracked frame.
VoiceRecording load_voice_recording(const std::filesystem::path& input, int sample_rate, FrameProcessor& processor);

}  // namespace lipdrive
