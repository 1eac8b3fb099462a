// Learning a voice model (core/voice_model.hpp) from a performer's own recordings: the sound
// and, at the video frames' times, the measures the video path tracked (docs/method.md 11).
// Pure computation on Eigen; the recordings are loaded by firmware_app/voice/voice_corpus.
#pragma once

#include "core/voice_model.hpp"

#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace lipdrive {

/// The video's measures at one frame, on the sound's timeline (0 = the first sample).
struct VoiceTargetFrame {
  double time_s = 0;
  std::array<float, kNumVoiceTargets> values{};  // open, width_fit, protrusion_3d, seal
  bool tracked = false;                          // the values are measured; else ignored
  bool speech = false;                           // inside a spoken word (a transcript, else the voice activity)
};

/// One recording: its sound and its tracked frames.
struct VoiceRecording {
  std::string name;
  std::vector<float> samples;  // mono, [-1, 1]
  int sample_rate = 0;
  std::vector<VoiceTargetFrame> targets;
  bool has_transcript = false;  // `speech` comes from a word alignment, not the voice activity
};

/// Every feature frame of `samples`.
std::vector<FeatureFrame> extract_features(const AudioFeatureSettings& settings, std::span<const float> samples);

/// The feature frame whose window is centred nearest to time `t_s` (may be < 0 or past the end).
std::int64_t frame_at(const AudioFeatureSettings& settings, double t_s);

/// `frames`' voice activity, frame by frame, as VoicePredictor hears it.
std::vector<bool> voice_activity(const VoiceActivitySettings& settings, std::span<const FeatureFrame> frames);

/// A recording without a transcript: marks as speech its target frames whose nearest feature
/// frame of `frames` (the recording's, extract_features) the voice activity hears, as training
/// and scoring both count speech (docs/voice.md).
void mark_voice_activity(VoiceRecording& recording, const AudioFeatureSettings& features,
                         const VoiceActivitySettings& activity, std::span<const FeatureFrame> frames);

struct VoiceTrainingSettings {
  AudioFeatureSettings features{.cepstra = 20};
  VoiceActivitySettings activity;
  VoiceContext context;
  int hidden = 32;             // tanh units of the hidden layer; 0: linear (ridge regression)
  double ridge = 0.01;         // L2 penalty (per sample: λ n I added to XᵀX)
  int gain_folds = 5;          // folds (by recording) of the out-of-fold predictions the gains come from
  float smoothing_s = 0;       // VoiceModel::smoothing_s
  float gate_s = 0.05f;        // VoiceModel::gate_s
  int epochs = 300;            // hidden layer: full-batch Adam steps
  double learning_rate = 0.01;
  std::uint32_t seed = 1;      // hidden layer: initial weights
};

/// Fits a model. Uses the tracked frames of every recording; the gains come from out-of-fold
/// predictions on their speech frames (from the transcript, else from the voice activity),
/// the rest pose from their silent frames. Throws
/// std::invalid_argument when the recordings are at another sample rate than the settings,
/// or hold too few tracked frames (fewer than the inputs, or no speech or no silence).
VoiceModel train_voice_model(std::span<const VoiceRecording> recordings, const VoiceTrainingSettings& settings);

/// Sound run through VoicePredictor: one output per feature frame (the frames before the first
/// prediction, and the last `lookahead`, hold the rest pose).
std::vector<VoiceOutput> predict_frames(const VoiceModel& model, std::span<const float> samples);

/// Of predict_frames' outputs, the one for time `t_s` (the nearest frame's; clamped to the ends).
const VoiceOutput& output_at(const VoiceModel& model, std::span<const VoiceOutput> frames, double t_s);

/// A recording run through VoicePredictor: the output at each target frame's time.
std::vector<VoiceOutput> predict_recording(const VoiceModel& model, const VoiceRecording& recording);

}  // namespace lipdrive
