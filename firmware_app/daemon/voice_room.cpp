#include "firmware_app/daemon/voice_room.hpp"

#include "drivers/thread_scheduling.hpp"

#include <fmt/format.h>

#include <span>

namespace lipdrive {
namespace {

constexpr std::chrono::milliseconds kAudioWait{100};

}  // namespace

VoiceRoom::VoiceRoom(std::unique_ptr<AudioSource> input, const VoiceModel& model)
    : input_(std::move(input)),
      input_name_(input_->describe()),
      features_(model.features),
      predictor_(model),
      frames_(static_cast<std::size_t>(kMaxAudioBlockFrames / model.features.hop + 1)),
      thread_(&VoiceRoom::run, this) {
  schedule_thread(thread_, "lipdrive-voice", 0);
}

VoiceRoom::~VoiceRoom() {
  stop_ = true;
  thread_.join();
}

void VoiceRoom::run() {
  AudioBlock block;
  while (!stop_.load(std::memory_order_relaxed)) {
    const AudioStatus status = input_->read(block, kAudioWait);
    input_lost_.store(status == AudioStatus::kDisconnected || status == AudioStatus::kEndOfStream,
                      std::memory_order_relaxed);
    if (status == AudioStatus::kEndOfStream) return;  // a recording's sound ended: nothing more to hear
    if (status == AudioStatus::kBlock) hear(block);
  }
}

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
  blocks_.fetch_add(1, std::memory_order_relaxed);
  if (!predicted) return;
  state.heard_ns = block.capture_time_ns + static_cast<std::int64_t>(block.frames * ns_per_sample);
  state_.publish(state);
}

std::string VoiceRoom::problem() const {
  if (input_lost_.load(std::memory_order_relaxed)) return fmt::format("voice input {} lost", input_name_);
  if (blocks() == 0) return fmt::format("no sound from the voice input {} yet", input_name_);
  return {};
}

std::string VoiceRoom::describe() const { return fmt::format("voice from {}", input_name_); }

}  // namespace lipdrive
