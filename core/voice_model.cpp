#include "core/voice_model.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace lipdrive {
namespace {

bool finite(const Eigen::MatrixXf& m) { return m.allFinite(); }

template <std::size_t N>
bool finite(const std::array<float, N>& values) {
  return std::ranges::all_of(values, [](float v) { return std::isfinite(v); });
}

// The most context a model may hold: two seconds back, 200 ms ahead.
constexpr double kMaxPastS = 2.0, kMaxLookaheadS = 0.2;

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
  return "";
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
