#include "firmware_app/voice/voice_corpus.hpp"

#include "drivers/audio_file.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/tables/grid_align.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <set>
#include <string>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

void require_file(const fs::path& file, std::string_view what) {
  std::error_code ec;
  if (!fs::exists(file, ec)) throw CommandError(fmt::format("{}: no such {}", file.string(), what), kExitNoInput);
}

DecodedAudio sound_of(const fs::path& file, int sample_rate) {
  try {
    return decode_audio(file, sample_rate);
  } catch (const AudioSourceError& e) {
    throw CommandError(e.what(), kExitDataError);
  }
}

std::array<float, kNumVoiceTargets> target_values(const MouthMeasures& m) {
  return {static_cast<float>(m.open), static_cast<float>(m.width_fit), static_cast<float>(m.protrusion_3d),
          static_cast<float>(m.seal)};
}

VoiceRecording load_clip(const fs::path& clip, int sample_rate, FrameProcessor& processor) {
  VoiceRecording recording;
  recording.name = clip.string();
  DecodedAudio sound = sound_of(clip, sample_rate);
  recording.samples = std::move(sound.samples);
  recording.sample_rate = sample_rate;

  SimulatedCameraOptions options;  // as fast as possible, once
  options.input = clip;
  std::optional<SimulatedCamera> camera;
  try {
    camera.emplace(options);
  } catch (const SourceError& e) {
    throw CommandError(e.what(), kExitDataError);
  }
  if (camera->independent_frames())
    throw CommandError(fmt::format("{}: an image or a folder has no sound; a voice needs a clip", clip.string()),
                       kExitDataError);
  processor.forget();
  Frame frame;
  for (GrabStatus status; (status = camera->grab(frame, std::chrono::milliseconds(1000))) != GrabStatus::kEndOfStream;) {
    if (status != GrabStatus::kFrame) continue;
    const FrameMeasurement& m = processor.process(frame.gray);
    VoiceTargetFrame target;
    target.time_s = frame.media_time_s - sound.start_s;
    target.tracked = m.tracked;
    if (m.tracked) target.values = target_values(m.measures);
    recording.targets.push_back(target);
  }

  const fs::path align = fs::path(clip).replace_extension(".align");
  std::error_code ec;
  if (fs::exists(align, ec)) {
    const std::vector<AlignedWord> words = read_grid_align(align);
    const std::set<int> speech = speech_frames(words);
    for (std::size_t i = 0; i < recording.targets.size(); ++i)
      recording.targets[i].speech = speech.contains(static_cast<int>(i));
    recording.has_transcript = true;
  }
  return recording;
}

}  // namespace

VoiceRecording load_voice_recording(const fs::path& input, int sample_rate, FrameProcessor& processor) {
  require_file(input, "clip");
  VoiceRecording recording = load_clip(input, sample_rate, processor);
  const bool any_tracked = std::ranges::any_of(recording.targets, [](const VoiceTargetFrame& t) { return t.tracked; });
  if (!any_tracked) throw CommandError(fmt::format("{}: no tracked frame to learn from", input.string()), kExitDataError);
  return recording;
}

}  // namespace lipdrive
