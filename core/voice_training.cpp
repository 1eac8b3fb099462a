#include "core/voice_training.hpp"

#include "core/statistics.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace lipdrive {
namespace {

/// The stacked, standardised context of every tracked target frame of some recordings, with
/// the targets, in one matrix each.
struct Design {
  Eigen::MatrixXd x;  // samples × inputs
  Eigen::MatrixXd y;  // samples × targets
  std::vector<bool> speech;
};

struct Standardisation {
  Eigen::VectorXd mean, scale;
};

Standardisation standardisation(std::span<const std::vector<FeatureFrame>> frames, int dims) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(dims), square = Eigen::VectorXd::Zero(dims);
  double count = 0;
  for (const auto& recording : frames)
    for (const FeatureFrame& f : recording) {
      const Eigen::VectorXd x = Eigen::Map<const Eigen::VectorXf>(f.values.data(), dims).cast<double>();
      sum += x;
      square += x.cwiseProduct(x);
      ++count;
    }
  Standardisation s;
  s.mean = sum / std::max(count, 1.0);
  s.scale = (square / std::max(count, 1.0) - s.mean.cwiseProduct(s.mean)).cwiseMax(1e-12).cwiseSqrt();
  return s;
}

/// One training sample: a feature frame of a recording and the measures at its time.
struct Sample {
  std::size_t recording = 0;
  std::int64_t frame = 0;
  std::array<double, kNumVoiceTargets> y{};
  bool speech = false;
};

/// The recording's video frame interval: the median time between consecutive target frames,
/// which a dropped frame or a gap in the camera does not move (NaN with fewer than two).
double frame_interval_s(const std::vector<VoiceTargetFrame>& targets) {
  std::vector<double> steps;
  for (std::size_t i = 1; i < targets.size(); ++i) steps.push_back(targets[i].time_s - targets[i - 1].time_s);
  return median(steps);
}

/// The samples of one recording: each tracked video frame at its nearest feature frame, and
/// every feature frame between two tracked video frames in a row at most 1.5 frame intervals
/// apart, the measures interpolated linearly between them (four times the samples at 100 and
/// 25 frames a second; the mouth moves smoothly within 40 ms). Across a longer gap (the camera
/// away while the sound goes on) nothing is known of the mouth: the sound there is no sample.
void collect_samples(const VoiceRecording& recording, std::size_t index, const AudioFeatureSettings& features,
                     std::vector<Sample>& out) {
  const auto& targets = recording.targets;
  const double max_fill_s = 1.5 * frame_interval_s(targets);
  for (std::size_t i = 0; i < targets.size(); ++i) {
    const VoiceTargetFrame& t = targets[i];
    if (!t.tracked) continue;
    Sample sample{index, frame_at(features, t.time_s), {}, t.speech};
    for (std::size_t k = 0; k < kNumVoiceTargets; ++k) sample.y[k] = t.values[k];
    out.push_back(sample);
    if (i + 1 >= targets.size() || !targets[i + 1].tracked || !(targets[i + 1].time_s - t.time_s <= max_fill_s))
      continue;
    const VoiceTargetFrame& next = targets[i + 1];
    for (std::int64_t k = sample.frame + 1; k < frame_at(features, next.time_s); ++k) {
      const double centre_s = static_cast<double>((k + 1) * features.hop - features.centre_lag()) / features.sample_rate;
      const double a = std::clamp((centre_s - t.time_s) / (next.time_s - t.time_s), 0.0, 1.0);
      Sample between{index, k, {}, a < 0.5 ? t.speech : next.speech};
      for (std::size_t m = 0; m < kNumVoiceTargets; ++m) between.y[m] = (1 - a) * t.values[m] + a * next.values[m];
      out.push_back(between);
    }
  }
}

Design design(std::span<const VoiceRecording> recordings, std::span<const std::vector<FeatureFrame>> frames,
              std::span<const std::size_t> use, const VoiceTrainingSettings& s, const Standardisation& z) {
  const AudioFeatureSettings& features = s.features;
  const VoiceContext& context = s.context;
  std::vector<Sample> samples;
  for (std::size_t r : use) collect_samples(recordings[r], r, features, samples);
  const int dims = features.dims(), taps = context.taps();
  Design d;
  d.x = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(samples.size()), taps * dims);
  d.y = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(samples.size()), kNumVoiceTargets);
  d.speech.reserve(samples.size());
  for (std::size_t row = 0; row < samples.size(); ++row) {
    const Sample& sample = samples[row];
    const std::vector<FeatureFrame>& f = frames[sample.recording];
    const auto n = static_cast<std::int64_t>(f.size());
    int tap = 0;
    // Frames before the recording's first or after its last read as the mean (zero).
    for (int offset = -(context.past / context.stride) * context.stride; offset <= context.lookahead;
         offset += context.stride, ++tap) {
      const std::int64_t k = sample.frame + offset;
      if (k < 0 || k >= n) continue;
      const auto& v = f[static_cast<std::size_t>(k)].values;
      d.x.row(static_cast<Eigen::Index>(row)).segment(tap * dims, dims) =
          ((Eigen::Map<const Eigen::VectorXf>(v.data(), dims).cast<double>() - z.mean).cwiseQuotient(z.scale))
              .transpose();
    }
    for (int k = 0; k < kNumVoiceTargets; ++k)
      d.y(static_cast<Eigen::Index>(row), k) = sample.y[static_cast<std::size_t>(k)];
    d.speech.push_back(sample.speech);
  }
  return d;
}

/// Ridge regression (Hoerl and Kennard 1970): W = (Xcᵀ Xc + λ n I)⁻¹ Xcᵀ Yc on centred X and
/// Y, bias = ȳ - W x̄. Returns W (targets × inputs) and the bias.
std::pair<Eigen::MatrixXd, Eigen::VectorXd> fit_ridge(const Eigen::MatrixXd& x, const Eigen::MatrixXd& y,
                                                      double ridge) {
  const Eigen::RowVectorXd x_mean = x.colwise().mean(), y_mean = y.colwise().mean();
  const Eigen::MatrixXd xc = x.rowwise() - x_mean, yc = y.rowwise() - y_mean;
  Eigen::MatrixXd gram = xc.transpose() * xc;
  gram.diagonal().array() += ridge * static_cast<double>(x.rows());
  const Eigen::MatrixXd w = gram.ldlt().solve(xc.transpose() * yc).transpose();
  return {w, (y_mean - x_mean * w.transpose()).transpose()};
}

/// A one-hidden-layer perceptron with a linear skip, out = W_s x + W_h tanh(V x + c) + b,
/// trained by full-batch Adam (Kingma and Ba 2015) on the mean squared error of the targets
/// standardised to unit variance, with an L2 penalty λ on every weight; the linear part starts
/// as the ridge solution and the hidden units at small random weights.
void fit_hidden_layer(const Design& d, const VoiceTrainingSettings& s, VoiceModel& model) {
  const Eigen::Index n = d.x.rows(), inputs = d.x.cols(), hidden = s.hidden;
  const Eigen::RowVectorXd y_mean = d.y.colwise().mean();
  const Eigen::RowVectorXd y_scale =
      ((d.y.rowwise() - y_mean).colwise().squaredNorm() / static_cast<double>(n)).cwiseMax(1e-12).cwiseSqrt();
  const Eigen::MatrixXd y = (d.y.rowwise() - y_mean).array().rowwise() / y_scale.array();

  auto [skip, bias] = fit_ridge(d.x, y, s.ridge);
  std::mt19937 random(s.seed);
  std::normal_distribution<double> normal(0.0, 1.0 / std::sqrt(static_cast<double>(inputs)));
  Eigen::MatrixXd v = Eigen::MatrixXd::NullaryExpr(hidden, inputs, [&] { return normal(random); });
  Eigen::VectorXd c = Eigen::VectorXd::Zero(hidden);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(kNumVoiceTargets, hidden);

  // Adam's moments, one pair per parameter block.
  struct Moments {
    Eigen::MatrixXd m, v;
  };
  const auto moments = [](const Eigen::MatrixXd& p) { return Moments{Eigen::MatrixXd::Zero(p.rows(), p.cols()), Eigen::MatrixXd::Zero(p.rows(), p.cols())}; };
  Eigen::MatrixXd c_matrix = c, bias_matrix = bias;
  Moments m_skip = moments(skip), m_bias = moments(bias_matrix), m_v = moments(v), m_c = moments(c_matrix),
          m_out = moments(out);
  constexpr double kBeta1 = 0.9, kBeta2 = 0.999, kEpsilon = 1e-8;
  const auto step = [&](Eigen::MatrixXd& p, const Eigen::MatrixXd& g, Moments& m, int t) {
    m.m = kBeta1 * m.m + (1 - kBeta1) * g;
    m.v = kBeta2 * m.v + (1 - kBeta2) * g.cwiseProduct(g);
    const double correction1 = 1 - std::pow(kBeta1, t), correction2 = 1 - std::pow(kBeta2, t);
    p.array() -= s.learning_rate * (m.m.array() / correction1) / ((m.v.array() / correction2).sqrt() + kEpsilon);
  };
  const double inv_n = 1.0 / static_cast<double>(n);
  for (int epoch = 1; epoch <= s.epochs; ++epoch) {
    const Eigen::MatrixXd h = ((d.x * v.transpose()).rowwise() + c_matrix.col(0).transpose()).array().tanh();
    const Eigen::MatrixXd prediction =
        (d.x * skip.transpose() + h * out.transpose()).rowwise() + bias_matrix.col(0).transpose();
    const Eigen::MatrixXd error = (prediction - y) * (2 * inv_n / kNumVoiceTargets);  // dLoss/dprediction
    const Eigen::MatrixXd back = (error * out).cwiseProduct((1 - h.array().square()).matrix());
    const Eigen::MatrixXd g_skip = error.transpose() * d.x + 2 * s.ridge * skip;
    const Eigen::MatrixXd g_out = error.transpose() * h + 2 * s.ridge * out;
    const Eigen::MatrixXd g_bias = error.colwise().sum().transpose();
    const Eigen::MatrixXd g_v = back.transpose() * d.x + 2 * s.ridge * v;
    const Eigen::MatrixXd g_c = back.colwise().sum().transpose();
    step(skip, g_skip, m_skip, epoch);
    step(out, g_out, m_out, epoch);
    step(bias_matrix, g_bias, m_bias, epoch);
    step(v, g_v, m_v, epoch);
    step(c_matrix, g_c, m_c, epoch);
  }
  // Back to the targets' own units.
  const Eigen::VectorXd scale = y_scale.transpose();
  model.hidden_weights = v.cast<float>();
  model.hidden_bias = c_matrix.col(0).cast<float>();
  model.weights.resize(kNumVoiceTargets, inputs + hidden);
  model.weights << (scale.asDiagonal() * skip).cast<float>(), (scale.asDiagonal() * out).cast<float>();
  model.bias = (scale.cwiseProduct(bias_matrix.col(0)) + y_mean.transpose()).cast<float>();
}

/// The model without its output scaling (gain 1), fitted on `use`.
VoiceModel fit(std::span<const VoiceRecording> recordings, std::span<const std::vector<FeatureFrame>> frames,
               std::span<const std::size_t> use, const VoiceTrainingSettings& s) {
  VoiceModel model;
  model.features = s.features;
  model.activity = s.activity;
  model.context = s.context;
  model.smoothing_s = s.smoothing_s;
  model.gate_s = s.gate_s;
  std::vector<std::vector<FeatureFrame>> used;
  for (std::size_t r : use) used.push_back(frames[r]);
  const Standardisation z = standardisation(used, s.features.dims());
  model.feature_mean = z.mean.cast<float>();
  model.feature_scale = z.scale.cast<float>();
  const Design d = design(recordings, frames, use, s, z);
  if (d.x.rows() <= d.x.cols())
    throw std::invalid_argument("voice training: " + std::to_string(d.x.rows()) + " tracked frames for " +
                                std::to_string(d.x.cols()) + " inputs; record more material");
  if (s.hidden > 0) {
    fit_hidden_layer(d, s, model);
  } else {
    const auto [w, b] = fit_ridge(d.x, d.y, s.ridge);
    model.weights = w.cast<float>();
    model.bias = b.cast<float>();
  }
  // The rest pose: the median of each measure over the silent tracked frames.
  for (int k = 0; k < kNumVoiceTargets; ++k) {
    std::vector<double> silent;
    for (Eigen::Index i = 0; i < d.y.rows(); ++i)
      if (!d.speech[static_cast<std::size_t>(i)]) silent.push_back(d.y(i, k));
    if (silent.empty()) throw std::invalid_argument("voice training: no silent tracked frame to learn the rest pose");
    model.rest[static_cast<std::size_t>(k)] = static_cast<float>(median(silent));
    model.gain[static_cast<std::size_t>(k)] = 1;
  }
  return model;
}

double mean_of(const std::vector<double>& v) {
  double sum = 0;
  for (double x : v) sum += x;
  return sum / static_cast<double>(v.size());
}

double deviation_of(const std::vector<double>& v) {
  const double m = mean_of(v);
  double sum = 0;
  for (double x : v) sum += (x - m) * (x - m);
  return std::sqrt(sum / static_cast<double>(v.size()));
}

}  // namespace

std::vector<FeatureFrame> extract_features(const AudioFeatureSettings& settings, std::span<const float> samples) {
  AudioFeatures features(settings);
  std::vector<FeatureFrame> frames(samples.size() / static_cast<std::size_t>(settings.hop) + 1);
  frames.resize(static_cast<std::size_t>(features.push(samples, frames)));
  return frames;
}

std::int64_t frame_at(const AudioFeatureSettings& s, double t_s) {
  return std::llround((t_s * s.sample_rate + s.centre_lag()) / s.hop) - 1;
}

std::vector<bool> voice_activity(const VoiceActivitySettings& settings, std::span<const FeatureFrame> frames) {
  VoiceActivity activity(settings);
  std::vector<bool> active;
  active.reserve(frames.size());
  for (const FeatureFrame& f : frames) active.push_back(activity.step(f.level_db));
  return active;
}

void mark_voice_activity(VoiceRecording& recording, const AudioFeatureSettings& features,
                         const VoiceActivitySettings& activity, std::span<const FeatureFrame> frames) {
  const std::vector<bool> active = voice_activity(activity, frames);
  for (VoiceTargetFrame& t : recording.targets) {
    const std::int64_t k = frame_at(features, t.time_s);
    t.speech = k >= 0 && k < static_cast<std::int64_t>(active.size()) && active[static_cast<std::size_t>(k)];
  }
}

VoiceModel train_voice_model(std::span<const VoiceRecording> given, const VoiceTrainingSettings& s) {
  if (const std::string problem = invalid_feature_settings(s.features); !problem.empty())
    throw std::invalid_argument("voice training: features: " + problem);
  if (s.hidden < 0 || s.hidden > kMaxVoiceHidden || !(s.ridge >= 0) || s.gain_folds < 2)
    throw std::invalid_argument("voice training: hidden units, ridge or folds out of range");
  if (const std::string problem = invalid_voice_activity(s.activity); !problem.empty())
    throw std::invalid_argument("voice training: voice activity: " + problem);
  std::vector<VoiceRecording> recordings(given.begin(), given.end());
  std::vector<std::vector<FeatureFrame>> frames;
  for (VoiceRecording& r : recordings) {
    if (r.sample_rate != s.features.sample_rate)
      throw std::invalid_argument("voice training: " + r.name + " is at " + std::to_string(r.sample_rate) +
                                  " Hz, the features at " + std::to_string(s.features.sample_rate) + " Hz");
    frames.push_back(extract_features(s.features, r.samples));
    if (!r.has_transcript) mark_voice_activity(r, s.features, s.activity, frames.back());
  }
  std::vector<std::size_t> all(recordings.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  VoiceModel model = fit(recordings, frames, all, s);

  // Gains: each recording predicted by a model that never saw it (folds by recording); the
  // spread of those predictions over each recording's speech frames against the video's, the
  // variances summed over recordings (the spread within a take, not between takes, is what
  // the figure shows).
  // A single recording is predicted by the model itself (its gains then come out a little low).
  const int folds = std::min<int>(s.gain_folds, static_cast<int>(recordings.size()));
  std::array<double, kNumVoiceTargets> truth_variance{}, predicted_variance{}, truth_sum{};
  std::size_t speech_frames = 0;
  for (int fold = 0; fold < std::max(folds, 1); ++fold) {
    std::vector<std::size_t> train, held_out;
    for (std::size_t i : all) (folds < 2 || static_cast<int>(i) % folds == fold ? held_out : train).push_back(i);
    const VoiceModel partial = folds < 2 ? model : fit(recordings, frames, train, s);
    for (std::size_t r : held_out) {
      const std::vector<VoiceOutput> outputs = predict_recording(partial, recordings[r]);
      for (std::size_t k = 0; k < kNumVoiceTargets; ++k) {
        std::vector<double> truth, predicted;
        for (std::size_t i = 0; i < outputs.size(); ++i) {
          const VoiceTargetFrame& t = recordings[r].targets[i];
          if (!t.tracked || !t.speech) continue;
          truth.push_back(t.values[k]);
          predicted.push_back(outputs[i].values[k]);
        }
        if (truth.size() < 2) continue;
        truth_variance[k] += deviation_of(truth) * deviation_of(truth) * static_cast<double>(truth.size());
        predicted_variance[k] += deviation_of(predicted) * deviation_of(predicted) * static_cast<double>(truth.size());
        truth_sum[k] += mean_of(truth) * static_cast<double>(truth.size());
        if (k == 0) speech_frames += truth.size();
      }
    }
  }
  if (speech_frames < 2) throw std::invalid_argument("voice training: no tracked speech frames");
  for (std::size_t k = 0; k < kNumVoiceTargets; ++k) {
    model.centre[k] = static_cast<float>(truth_sum[k] / static_cast<double>(speech_frames));
    model.gain[k] = predicted_variance[k] > 0
                        ? static_cast<float>(std::clamp(std::sqrt(truth_variance[k] / predicted_variance[k]),
                                                        double{kMinVoiceGain}, double{kMaxVoiceGain}))
                        : 1.0f;
  }
  return model;
}

std::vector<VoiceOutput> predict_frames(const VoiceModel& model, std::span<const float> samples) {
  const std::vector<FeatureFrame> frames = extract_features(model.features, samples);
  VoicePredictor predictor(model);
  VoiceOutput rest;
  rest.values = model.rest;
  std::vector<VoiceOutput> by_frame(std::max<std::size_t>(frames.size(), 1), rest);
  VoiceOutput out;
  for (const FeatureFrame& f : frames)
    if (predictor.push(f, out)) by_frame[out.frame] = out;
  return by_frame;
}

const VoiceOutput& output_at(const VoiceModel& model, std::span<const VoiceOutput> frames, double t_s) {
  const std::int64_t k =
      std::clamp<std::int64_t>(frame_at(model.features, t_s), 0, static_cast<std::int64_t>(frames.size()) - 1);
  return frames[static_cast<std::size_t>(k)];
}

std::vector<VoiceOutput> predict_recording(const VoiceModel& model, const VoiceRecording& recording) {
  const std::vector<VoiceOutput> by_frame = predict_frames(model, recording.samples);
  std::vector<VoiceOutput> at_targets;
  at_targets.reserve(recording.targets.size());
  for (const VoiceTargetFrame& t : recording.targets) at_targets.push_back(output_at(model, by_frame, t.time_s));
  return at_targets;
}

}  // namespace lipdrive
