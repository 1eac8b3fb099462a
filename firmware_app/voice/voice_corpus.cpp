#include "firmware_app/voice/voice_corpus.hpp"

#include "drivers/audio_file.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/recording.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "firmware_app/tables/grid_align.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

// How far a take's last row may lie past the end of its sound, or its sound past its last row:
// the recorder's sound is as long as its rows within two of the listener's 10 ms blocks (tests/test_voice_room.cpp); a
// tenth of a second leaves room for a sound card's longer period and stays under three video frames.
constexpr double kTakeSoundSlack_s = 0.1;

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
  fit_take_identity(clip, Rotation::k0, processor);  // the first clip's, kept for the others (one performer)
  processor.forget(FaceTracker::Next::kVideo);
  Frame frame;
  std::vector<int> frame_numbers;  // each target's place on the video's timeline
  for (GrabStatus status;
       (status = camera->grab(frame, std::chrono::milliseconds(1000))) != GrabStatus::kEndOfStream;) {
    if (status != GrabStatus::kFrame) continue;
    const FrameMeasurement& m = processor.process(frame.gray, frame.cr);
    frame_numbers.push_back(static_cast<int>(std::lround(frame.media_time_s * camera->frame_rate())));
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
    const std::vector<FrameRange> speech = speech_frames(words, camera->frame_rate());
    for (std::size_t i = 0; i < recording.targets.size(); ++i)
      recording.targets[i].speech = contains(speech, frame_numbers[i]);
    recording.has_transcript = true;
  }
  return recording;
}

/// A take's rows as targets on its sound's timeline: the sound's first sample was captured at
/// the first row's capture_time_ns.
VoiceRecording load_take(const fs::path& take, int sample_rate) {
  const fs::path wav = fs::path(take).replace_extension(".wav");
  require_file(wav, "take sound (takes record their sound when the daemon has a [voice] input)");
  const CsvTable table = read_csv_table(take);
  const std::vector<double> time_ns = numeric_column(table, "capture_time_ns");
  const std::vector<double> tracked = numeric_column(table, "tracked");
  const std::array<std::vector<double>, kNumVoiceTargets> columns = {
      numeric_column(table, "open"), numeric_column(table, "width_fit"), numeric_column(table, "protrusion_3d"),
      numeric_column(table, "seal")};
  VoiceRecording recording;
  recording.name = take.string();
  recording.samples = sound_of(wav, sample_rate).samples;
  recording.sample_rate = sample_rate;
  for (std::size_t i = 0; i < time_ns.size(); ++i) {
    // The rows' capture times place the measures on the sound: one missing, or going back, places none.
    if (!std::isfinite(time_ns[i]) || (i > 0 && time_ns[i] < time_ns[i - 1]))
      throw CommandError(
          fmt::format("{}:{}: capture_time_ns {}", take.string(), table.line_numbers[i],
                      std::isfinite(time_ns[i]) ? "earlier than the row before's" : "missing (blank or not finite)"),
          kExitDataError);
    VoiceTargetFrame target;
    target.time_s = (time_ns[i] - time_ns[0]) * 1e-9;
    target.tracked = tracked[i] == 1;
    for (int k = 0; k < kNumVoiceTargets; ++k) {
      target.values[static_cast<std::size_t>(k)] = static_cast<float>(columns[static_cast<std::size_t>(k)][i]);
      target.tracked = target.tracked && std::isfinite(columns[static_cast<std::size_t>(k)][i]);
    }
    recording.targets.push_back(target);
  }
  // Rows past the end of the sound would be paired with no sound; beyond kTakeSoundSlack_s the
  // sound is not the one recorded with them (another take's, or one cut short).
  const double sound_s = static_cast<double>(recording.samples.size()) / sample_rate;
  if (!recording.targets.empty() && recording.targets.back().time_s > sound_s + kTakeSoundSlack_s) {
    const auto past_end =
        std::ranges::find_if(recording.targets, [&](const VoiceTargetFrame& t) { return t.time_s > sound_s; });
    const auto first = static_cast<std::size_t>(past_end - recording.targets.begin());
    throw CommandError(fmt::format("{}:{}: this row and the {} after it lie up to {:.2f} s past the end of its sound "
                                   "{} ({:.2f} s long; another take's, or one cut short)",
                                   take.string(), table.line_numbers[first], recording.targets.size() - first - 1,
                                   recording.targets.back().time_s - sound_s, wav.string(), sound_s),
                       kExitDataError);
  }
  // The recorder ends the sound with the last row: a sound that runs on past it by more than the
  // slack is not this take's, and its rows would be paired with another take's sound.
  const double last_row_s = recording.targets.empty() ? 0 : recording.targets.back().time_s;
  if (sound_s > last_row_s + kTakeSoundSlack_s)
    throw CommandError(
        fmt::format("{}: {:.2f} s long, {:.2f} s past the last of the {} rows of {}; another take's sound",
                    wav.string(), sound_s, sound_s - last_row_s, recording.targets.size(), take.string()),
        kExitDataError);
  return recording;
}

}  // namespace

VoiceRecording load_voice_recording(const fs::path& input, int sample_rate, FrameProcessor& processor) {
  require_file(input, "clip or take");
  VoiceRecording recording =
      input.extension() == ".csv" ? load_take(input, sample_rate) : load_clip(input, sample_rate, processor);
  const bool any_tracked = std::ranges::any_of(recording.targets, [](const VoiceTargetFrame& t) { return t.tracked; });
  if (!any_tracked)
    throw CommandError(fmt::format("{}: no tracked frame to learn from", input.string()), kExitDataError);
  return recording;
}

}  // namespace lipdrive
