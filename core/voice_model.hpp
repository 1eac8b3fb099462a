// The per-performer voice model (docs/method.md 11): the mouth measures of the video path
// (open, width, protrusion, seal) predicted from the feature frames of the performer's speech,
// and the streaming predictor that runs it live and offline alike.
//
// Each prediction looks at a context of feature frames around its own time: `past` frames
// before it and `lookahead` frames after it, every `stride`-th one, each standardised; a
// hidden layer of tanh units may follow (a one-layer perceptron on the stacked frames); the
// output is linear (Edge, Hilton and Jackson 2009: MFCCs in a 5-frame context, a per-speaker
// regression). Each output is then scaled about its training mean by a gain chosen so that
// its spread matches the video's (ridge regression shrinks it: the figure would under-
// articulate), smoothed by a one-pole low-pass, and held at the rest pose while the voice
// activity detector hears no speech (with a short cross-fade).
#pragma once

#include "core/audio_features.hpp"
#include "core/voice_activity.hpp"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <string_view>

namespace lipdrive {

/// What the voice model predicts: the measures the drive signals come from
/// (core/calibration.hpp drive_signals).
enum class VoiceTarget : int { kOpen, kWidth, kProtrusion, kSeal };
inline constexpr int kNumVoiceTargets = 4;
/// "open", "width", "protrusion", "seal": the drive signals they become.
std::string_view voice_target_name(VoiceTarget target);

struct VoiceContext {
  int past = 20;      // feature frames before the prediction's own frame
  int lookahead = 4;  // feature frames after it: the wait, in frames, before a prediction is made
  int stride = 2;     // every stride-th frame of the context, counting from the prediction's own
  /// Frames stacked: offsets -past..lookahead in steps of stride, 0 always among them.
  int taps() const { return past / stride + lookahead / stride + 1; }
  bool operator==(const VoiceContext&) const = default;
};

inline constexpr int kMaxVoiceTaps = 64;
inline constexpr int kMaxVoiceHidden = 256;
/// Training's output gains lie in this range (voice_training.cpp): a gain is clamped rather
/// than multiply a nearly flat prediction without end.
inline constexpr float kMinVoiceGain = 0.25f, kMaxVoiceGain = 4.0f;

struct VoiceModel {
  AudioFeatureSettings features;
  VoiceActivitySettings activity;
  VoiceContext context;
  Eigen::VectorXf feature_mean, feature_scale;  // per feature dimension: z = (x - mean) / scale
  Eigen::MatrixXf hidden_weights;               // H × inputs (inputs = taps · dims); H = 0: linear
  Eigen::VectorXf hidden_bias;                  // H
  Eigen::MatrixXf weights;                      // targets × (inputs + H), rows in VoiceTarget order
  Eigen::VectorXf bias;                         // targets
  std::array<float, kNumVoiceTargets> centre{}, gain{};  // out = centre + gain (raw - centre)
  std::array<float, kNumVoiceTargets> rest{};            // the measures while the voice is silent
  float smoothing_s = 0.02f;                             // the output low-pass's time constant
  float gate_s = 0.05f;                                  // the cross-fade to and from rest

  int inputs() const { return context.taps() * features.dims(); }
  int hidden() const { return static_cast<int>(hidden_weights.rows()); }
  /// The time from a sample's capture to the prediction that first hears it: the look-ahead
  /// plus half the analysis window (the newest frame's centre to its last sample).
  double delay_s() const;
};

/// Why the parts of a model do not fit together (sizes, finite values, ranges), or holds a
/// value no training produces (voice_model.cpp gives each bound's reason), or "".
std::string invalid_voice_model(const VoiceModel& model);

/// One prediction: the measures at feature frame `frame` (its window's centre).
struct VoiceOutput {
  std::array<float, kNumVoiceTargets> values{};
  bool active = false;     // the voice was heard (at the newest frame)
  float gate = 0;          // 1: the prediction drives; 0: the rest pose
  std::uint64_t frame = 0;
};

/// Runs a model frame by frame: push() each feature frame in order; once the look-ahead has
/// arrived, each push() completes the prediction for the frame `lookahead` back. Construction
/// allocates every buffer; push() allocates nothing.
class VoicePredictor {
 public:
  /// Throws std::invalid_argument naming what is wrong with the model.
  explicit VoicePredictor(const VoiceModel& model);

  /// false while the first frames fill the look-ahead.
  bool push(const FeatureFrame& frame, VoiceOutput& out);
  void reset();
  const VoiceModel& model() const { return model_; }

 private:
  VoiceModel model_;
  VoiceActivity activity_;
  Eigen::MatrixXf ring_;  // standardised frames (one per column), the newest at head_
  int head_ = -1;
  std::uint64_t seen_ = 0;
  Eigen::VectorXf input_, hidden_, raw_;
  std::array<float, kNumVoiceTargets> smoothed_{};
  float gate_ = 0;
  bool primed_ = false;
};

}  // namespace lipdrive
