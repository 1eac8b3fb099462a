// The voice room ([voice], docs/voice.md): the performer's microphone heard through the
// performer's voice model, so that the drive can hand over to the voice while the face is lost.
//
// Thread model: the VoiceRoom owns the feature extractor, the predictor and an AudioListener
// (firmware_app/daemon/audio_listener.hpp) whose thread reads the input block after block and
// hands each to hear(): feature frames and predictions (no heap allocation per block), the
// newest prediction published through a seqlock (latest wins). Any thread reads it with
// latest() (lock-free, no allocation). The listener is the last member, so its thread is
// joined before anything it uses goes; the Daemon declares the room before the pipeline that
// reads it, so the pipeline's threads are joined first.
#pragma once

#include "core/audio_features.hpp"
#include "core/voice_model.hpp"
#include "drivers/audio_source.hpp"
#include "firmware_app/daemon/audio_listener.hpp"
#include "firmware_app/daemon/latest_frame.hpp"
#include "firmware_app/daemon/take_sound.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace lipdrive {

/// The newest prediction of the voice; trivially copyable for the seqlock.
struct VoiceState {
  std::array<float, kNumVoiceTargets> measures{};  // open, width_fit, protrusion_3d, seal (VoiceTarget order)
  bool active = false;                             // voice activity at the newest feature frame
  std::int64_t time_ns = 0;                        // CLOCK_MONOTONIC of the moment predicted (its window's centre)
  std::int64_t heard_ns = 0;  // CLOCK_MONOTONIC of the end of the newest block (past its last sample)
};

class VoiceRoom {
 public:
  /// Takes the input; starts hearing it (at the frame path's `realtime_priority`, AudioListener),
  /// and passing every block to `sound` when given (takes' sound; it must outlive the room).
  /// Throws std::invalid_argument when the model cannot be run (core/voice_model.hpp),
  /// std::runtime_error when aubio cannot make its objects.
  VoiceRoom(std::unique_ptr<AudioSource> input, const VoiceModel& model, TakeSound* sound = nullptr,
            int realtime_priority = 0);
  VoiceRoom(const VoiceRoom&) = delete;
  VoiceRoom& operator=(const VoiceRoom&) = delete;

  /// Any thread: the newest prediction and its version (0: none yet).
  std::uint32_t latest(VoiceState& state) const { return state_.read(state); }
  /// Any thread: waits until a prediction newer than version `seen` or `timeout` passes.
  void wait_newer(std::uint32_t seen, std::chrono::nanoseconds timeout) { state_.wait_newer(seen, timeout); }
  /// Main thread, for the status line: why no sound is heard; "" when fine.
  std::string problem() const;
  std::string describe() const;
  /// Blocks heard so far.
  std::uint64_t blocks() const { return listener_.blocks(); }

 private:
  void hear(const AudioBlock& block);

  AudioFeatures features_;            // the listener's thread's
  VoicePredictor predictor_;          // the listener's thread's
  std::vector<FeatureFrame> frames_;  // the listener's thread's: the feature frames of one block
  Published<VoiceState> state_;
  TakeSound* sound_;        // the listener's thread pushes into it
  AudioListener listener_;  // last: its thread uses the members above
};

}  // namespace lipdrive
