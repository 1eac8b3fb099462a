// The voice room ([voice], docs/voice.md): the performer's microphone heard through the
// performer's voice model, so that the drive can hand over to the voice while the face is lost.
//
// Thread model: the VoiceRoom owns its AudioSource, the feature extractor and the predictor,
// and one thread of its own that uses them: it reads block after block, turns each into feature
// frames and predictions (no heap allocation per block) and publishes the newest prediction
// through a seqlock (latest wins). Any thread reads it with latest() (lock-free, no
// allocation). The thread starts at construction and is joined by the destructor before any
// member it uses goes; the Daemon declares the room before the pipeline that reads it, so the
// pipeline's threads are joined first.
#pragma once

#include "core/audio_features.hpp"
#include "core/voice_model.hpp"
#include "drivers/audio_source.hpp"
#include "firmware_app/daemon/latest_frame.hpp"

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
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
  /// Takes the input; starts hearing it. Throws std::invalid_argument when the model cannot be
  /// run (core/voice_model.hpp), std::runtime_error when aubio cannot make its objects.
  VoiceRoom(std::unique_ptr<AudioSource> input, const VoiceModel& model);
  ~VoiceRoom();
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
  std::uint64_t blocks() const { return blocks_.load(std::memory_order_relaxed); }

 private:
  void run();
  void hear(const AudioBlock& block);

  std::unique_ptr<AudioSource> input_;  // the thread's
  std::string input_name_;
  AudioFeatures features_;            // the thread's
  VoicePredictor predictor_;          // the thread's
  std::vector<FeatureFrame> frames_;  // the thread's: the feature frames of one block
  Published<VoiceState> state_;
  std::atomic<std::uint64_t> blocks_{0};
  std::atomic<bool> input_lost_{false};
  std::atomic<bool> stop_{false};
  std::thread thread_;  // last: it uses the members above
};

}  // namespace lipdrive
