#include "core/voice_model.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string>
#include <tuple>

namespace lipdrive {
namespace {

bool finite(const Eigen::MatrixXf& m) { return m.allFinite(); }

template <std::size_t N>
bool finite(const std::array<float, N>& values) {
  return std::ranges::all_of(values, [](float v) { return std::isfinite(v); });
}

// The most context a model may hold: two seconds back, 200 ms ahead.
constexpr double kMaxPastS = 2.0, kMaxLookaheadS = 0.2;

// A feature is the log of a mel band energy, floored at 1e-10 (ln: -23.0) and, for sound in
// [-1, 1], far below 1e10 (+23.0), or a cepstrum of those logs, whose orthonormal DCT keeps their
// norm: |c| <= sqrt(64 bands) · 23.0 = 184 (audio_features.cpp). Their training mean lies within
// that, their standard deviation below it (GRID speech: |mean| <= 62, scale <= 14.3 at 64 bands).
constexpr float kMaxFeatureMagnitude = 200;
// Training floors each feature's variance at 1e-12, its scale at 1e-6; a tenth of that is the margin.
constexpr float kMinFeatureScale = 1e-7f;
// The inputs are standardised and the targets are measures over d spread by less than 1 d (seal
// within [0, 1]): ridge weights stay below 1 (GRID: 0.27 at --ridge 0 on a single clip), and Adam
// (beta1 0.9, beta2 0.999) moves a weight by at most 3.2 learning rates a step: 3.2e5 at `voice
// train`'s largest --learning-rate 1 over its most --epochs, 100000 (GRID at --hidden 256
// --learning-rate 1 --epochs 3000: 66). Biases alike. A weight of 1e7 would move the mouth 1e7 d
// for one standard deviation of one feature.
constexpr float kMaxVoiceWeight = 1e7f;
// Centre and rest are mouth measures over d, the eyes-to-nose-tip distance (docs/method.md 4):
// the face is some 4 d from brow to chin (GRID: at most 1.4).
constexpr float kMaxVoiceMeasure = 10;

/// The shortest decimal that reads back as `value`: 1e+38, not std::to_string's 39 digits.
std::string decimal(float value) {
  char text[32];
  return {text, std::to_chars(text, text + sizeof text, value).ptr};
}

/// "WHAT[i] is V, beyond ±BOUND" (WHAT[r, c] for a matrix) for the first value beyond `bound`, or "".
std::string beyond(std::string_view what, const Eigen::MatrixXf& values, float bound) {
  for (Eigen::Index r = 0; r < values.rows(); ++r)
    for (Eigen::Index c = 0; c < values.cols(); ++c)
      if (std::abs(values(r, c)) > bound)
        return std::string(what) + '[' + std::to_string(r) + (values.cols() > 1 ? ", " + std::to_string(c) : "") +
               "] is " + decimal(values(r, c)) + ", beyond ±" + decimal(bound);
  return "";
}

/// The first value of the model that no training produces (the bounds above), or "".
std::string implausible_value(const VoiceModel& m) {
  const auto measures = [](const std::array<float, kNumVoiceTargets>& values) {
    return Eigen::Map<const Eigen::VectorXf>(values.data(), kNumVoiceTargets);
  };
  const std::tuple<const char*, Eigen::MatrixXf, float> bounded[] = {
      {"feature mean", m.feature_mean, kMaxFeatureMagnitude},
      {"feature scale", m.feature_scale, kMaxFeatureMagnitude},
      {"hidden weights", m.hidden_weights, kMaxVoiceWeight},
      {"hidden bias", m.hidden_bias, kMaxVoiceWeight},
      {"weights", m.weights, kMaxVoiceWeight},
      {"bias", m.bias, kMaxVoiceWeight},
      {"centre", measures(m.centre), kMaxVoiceMeasure},
      {"rest", measures(m.rest), kMaxVoiceMeasure}};
  const std::string reason = ": no training produces that";
  for (const auto& [what, values, bound] : bounded)
    if (const std::string problem = beyond(what, values, bound); !problem.empty()) return problem + reason;
  if (m.feature_scale.minCoeff() < kMinFeatureScale)
    return "feature scale " + decimal(m.feature_scale.minCoeff()) + " is below " + decimal(kMinFeatureScale) + reason;
  if (!std::ranges::all_of(m.gain, [](float g) { return g >= kMinVoiceGain && g <= kMaxVoiceGain; }))
    return "a gain outside " + decimal(kMinVoiceGain) + ".." + decimal(kMaxVoiceGain) + reason;
  return "";
}

}  // namespace

std::string_view voice_target_name(VoiceTarget target) {
  switch (target) {
    case VoiceTarget::kOpen: return "open";
    case VoiceTarget::kWidth: return "width";
    case VoiceTarget::kProtrusion: return "protrusion";
    case VoiceTarget::kSeal: return "seal";
  }
  return "?";
}

double VoiceModel::delay_s() const {
  return (static_cast<double>(context.lookahead) * features.hop + features.centre_lag()) / features.sample_rate;
}

std::string invalid_voice_model(const VoiceModel& m) {
  if (const std::string problem = invalid_feature_settings(m.features); !problem.empty()) return "features: " + problem;
  const double frame_s = static_cast<double>(m.features.hop) / m.features.sample_rate;
  const VoiceContext& c = m.context;
  if (c.stride < 1 || c.past < 0 || c.lookahead < 0 || c.past * frame_s > kMaxPastS + 1e-9 ||
      c.lookahead * frame_s > kMaxLookaheadS + 1e-9 || c.taps() > kMaxVoiceTaps)
    return "context out of range (stride >= 1, at most 2 s back, 200 ms ahead, 64 frames stacked)";
  if (const std::string problem = invalid_voice_activity(m.activity); !problem.empty())
    return "voice activity: " + problem;
  const Eigen::Index dims = m.features.dims(), inputs = m.inputs(), hidden = m.hidden_weights.rows();
  if (m.feature_mean.size() != dims || m.feature_scale.size() != dims) return "feature standardisation: wrong size";
  if (!finite(m.feature_mean) || !(m.feature_scale.array() > 0).all() || !finite(m.feature_scale))
    return "feature standardisation: not finite or not positive";
  if (hidden > kMaxVoiceHidden) return "more than 256 hidden units";
  if (hidden > 0 && (m.hidden_weights.cols() != inputs || m.hidden_bias.size() != hidden))
    return "hidden layer: wrong size";
  if (hidden == 0 && m.hidden_bias.size() != 0) return "hidden layer: bias without weights";
  if (m.weights.rows() != kNumVoiceTargets || m.weights.cols() != inputs + hidden || m.bias.size() != kNumVoiceTargets)
    return "output layer: wrong size";
  if (!finite(m.hidden_weights) || !finite(m.hidden_bias) || !finite(m.weights) || !finite(m.bias))
    return "weights not finite";
  if (!finite(m.centre) || !finite(m.gain) || !finite(m.rest)) return "output scaling not finite";
  if (!(m.smoothing_s >= 0 && m.smoothing_s < 10 && m.gate_s >= 0 && m.gate_s < 10))
    return "smoothing or gate time out of range";
  return implausible_value(m);
}

VoicePredictor::VoicePredictor(const VoiceModel& model) : model_(model), activity_(model.activity) {
  if (const std::string problem = invalid_voice_model(model_); !problem.empty())
    throw std::invalid_argument("voice model: " + problem);
  const VoiceContext& c = model_.context;
  ring_ = Eigen::MatrixXf::Zero(model_.features.dims(), c.past + c.lookahead + 1);
  input_ = Eigen::VectorXf::Zero(model_.inputs());
  hidden_ = Eigen::VectorXf::Zero(model_.hidden());
  raw_ = Eigen::VectorXf::Zero(kNumVoiceTargets);
}

void VoicePredictor::reset() {
  activity_.reset();
  ring_.setZero();
  head_ = -1;
  seen_ = 0;
  gate_ = 0;
  primed_ = false;
}

bool VoicePredictor::push(const FeatureFrame& frame, VoiceOutput& out) {
  const VoiceModel& m = model_;
  const int span = static_cast<int>(ring_.cols()), dims = m.features.dims();
  head_ = (head_ + 1) % span;
  ring_.col(head_) = (Eigen::Map<const Eigen::VectorXf>(frame.values.data(), dims) - m.feature_mean)
                         .cwiseQuotient(m.feature_scale);
  ++seen_;
  const bool active = activity_.step(frame.level_db);
  if (seen_ < static_cast<std::uint64_t>(span)) return false;

  // The stacked context around the prediction's frame, `lookahead` behind the newest.
  const VoiceContext& c = m.context;
  const int own = head_ - c.lookahead;
  int tap = 0;
  for (int offset = -(c.past / c.stride) * c.stride; offset <= c.lookahead; offset += c.stride, ++tap)
    input_.segment(tap * dims, dims) = ring_.col(((own + offset) % span + span) % span);
  raw_.noalias() = m.weights.leftCols(input_.size()) * input_;
  if (m.hidden() > 0) {
    hidden_.noalias() = m.hidden_weights * input_;
    hidden_ = (hidden_ + m.hidden_bias).array().tanh().matrix();
    raw_.noalias() += m.weights.rightCols(m.hidden()) * hidden_;
  }
  raw_ += m.bias;

  const float frame_s = static_cast<float>(m.features.hop) / static_cast<float>(m.features.sample_rate);
  const float follow = m.smoothing_s > 0 ? 1 - std::exp(-frame_s / m.smoothing_s) : 1.0f;
  const float gate_step = m.gate_s > 0 ? frame_s / m.gate_s : 1.0f;
  gate_ = std::clamp(gate_ + (active ? gate_step : -gate_step), 0.0f, 1.0f);
  for (std::size_t t = 0; t < kNumVoiceTargets; ++t) {
    const float scaled = m.centre[t] + m.gain[t] * (raw_[static_cast<Eigen::Index>(t)] - m.centre[t]);
    smoothed_[t] = primed_ ? smoothed_[t] + follow * (scaled - smoothed_[t]) : scaled;
    out.values[t] = m.rest[t] + gate_ * (smoothed_[t] - m.rest[t]);
  }
  primed_ = true;
  out.values[static_cast<std::size_t>(VoiceTarget::kSeal)] =
      std::clamp(out.values[static_cast<std::size_t>(VoiceTarget::kSeal)], 0.0f, 1.0f);
  out.active = active;
  out.gate = gate_;
  out.frame = frame.index - static_cast<std::uint64_t>(c.lookahead);
  return true;
}

}  // namespace lipdrive
