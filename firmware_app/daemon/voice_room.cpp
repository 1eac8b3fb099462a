#include "firmware_app/daemon/voice_room.hpp"

#include <fmt/format.h>

#include <span>

namespace lipdrive {

VoiceRoom::VoiceRoom(std::unique_ptr<AudioSource> input, const VoiceModel& model, TakeSound* sound,
                     int realtime_priority)
    : features_(model.features),
      predictor_(model),
      frames_(static_cast<std::size_t>(kMaxAudioBlockFrames / model.features.hop + 1)),
      sound_(sound),
      listener_(std::move(input), "lipdrive-voice", realtime_priority, [this](const AudioBlock& block) {
        hear(block);
        if (sound_) sound_->push(block);
      }) {}

void VoiceRoom::hear(const AudioBlock& block) {
  const AudioFeatureSettings& f = features_.settings();
  const int lag = f.centre_lag() + predictor_.model().context.lookahead * f.hop;
  // The j-th frame completed in this block ends (hop - pending) + j hop samples into it.
  const int first_end = f.hop - features_.pending();
  const int count = features_.push({block.samples.data(), static_cast<std::size_t>(block.frames)}, frames_);
  const double ns_per_sample = 1e9 / block.sample_rate;
  VoiceState state;
  VoiceOutput out;
  bool predicted = false;
  for (int j = 0; j < count; ++j) {
    if (!predictor_.push(frames_[static_cast<std::size_t>(j)], out)) continue;
    predicted = true;
    state.measures = out.values;
    state.active = out.active;
    state.time_ns = block.capture_time_ns + static_cast<std::int64_t>((first_end + j * f.hop - lag) * ns_per_sample);
  }
  if (!predicted) return;
  state.heard_ns = block.capture_time_ns + static_cast<std::int64_t>(block.frames * ns_per_sample);
  state_.publish(state);
}

std::string VoiceRoom::problem() const {
  if (listener_.input_lost()) return fmt::format("voice input {} lost", listener_.input_name());
  if (blocks() == 0) return fmt::format("no sound from the voice input {} yet", listener_.input_name());
  return {};
}

std::string VoiceRoom::describe() const { return fmt::format("voice from {}", listener_.input_name()); }

}  // namespace lipdrive
