#include "core/metrics.hpp"

#include "core/statistics.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace lipdrive {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Pairs {
  std::vector<double> truth;
  std::vector<double> output;
};

Pairs finite_pairs(std::span<const double> truth, std::span<const double> output) {
  Pairs pairs;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (std::isnan(truth[i]) || std::isnan(output[i])) continue;
    pairs.truth.push_back(truth[i]);
    pairs.output.push_back(output[i]);
  }
  return pairs;
}

/// (v - min) / (max - min); a constant series maps to zeros.
std::vector<double> min_max_scaled(const std::vector<double>& values) {
  const auto [lowest, highest] = std::minmax_element(values.begin(), values.end());
  const double range = *highest - *lowest;
  std::vector<double> scaled(values.size(), 0.0);
  if (range > 0) {
    std::transform(values.begin(), values.end(), scaled.begin(),
                   [low = *lowest, range](double v) { return (v - low) / range; });
  }
  return scaled;
}

double mean(const std::vector<double>& values) {
  double sum = 0;
  for (double v : values) sum += v;
  return sum / static_cast<double>(values.size());
}

double root_mean_square_difference(const std::vector<double>& a, const std::vector<double>& b) {
  double sum = 0;
  for (std::size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(sum / static_cast<double>(a.size()));
}

}  // namespace

SeriesAgreement compare_series(std::span<const double> truth, std::span<const double> output) {
  if (truth.size() != output.size()) {
    throw std::invalid_argument("compare_series: the series differ in length");
  }
  const Pairs pairs = finite_pairs(truth, output);
  const std::size_t n = pairs.truth.size();
  if (n == 0) return {0, kNaN, kNaN, kNaN, kNaN, kNaN};

  SeriesAgreement result;
  result.pairs_used = static_cast<int>(n);
  result.rmse_scaled = root_mean_square_difference(min_max_scaled(pairs.truth), min_max_scaled(pairs.output));

  double abs_sum = 0;
  double abs_max = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double error = std::abs(pairs.output[i] - pairs.truth[i]);
    abs_sum += error;
    abs_max = std::max(abs_max, error);
  }
  result.mae = abs_sum / static_cast<double>(n);
  result.max_abs_error = abs_max;

  // Pearson r = cov(z, ẑ) / (σ(z) σ(ẑ)), from centred sums (two passes, stable).
  const double truth_mean = mean(pairs.truth);
  const double output_mean = mean(pairs.output);
  double cross = 0, truth_square = 0, output_square = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double dz = pairs.truth[i] - truth_mean;
    const double dzhat = pairs.output[i] - output_mean;
    cross += dz * dzhat;
    truth_square += dz * dz;
    output_square += dzhat * dzhat;
  }
  // Clamped because rounding can push a perfect correlation just past ±1.
  result.pearson_r = (truth_square > 0 && output_square > 0)
                         ? std::clamp(cross / std::sqrt(truth_square * output_square), -1.0, 1.0)
                         : kNaN;
  result.std_ratio = truth_square > 0 ? std::sqrt(output_square / truth_square) : kNaN;
  return result;
}

bool is_bilabial_word(std::string_view word) {
  constexpr std::array<std::string_view, 8> kWords{"bin", "blue", "by", "place", "please", "b", "p", "m"};
  return std::find(kWords.begin(), kWords.end(), word) != kWords.end();
}

ClosureMetric closure_metric(std::span<const double> values, std::span<const WordFrames> words,
                             double frames_per_second, std::span<const double> scale_by) {
  const int n = static_cast<int>(values.size());
  const auto widening = static_cast<int>(std::lround(ClosureMetric::kWidening_s * frames_per_second));
  const auto silence_delay = static_cast<int>(std::lround(ClosureMetric::kSilenceDelay_s * frames_per_second));
  // Min-max scaled over the tracked frames; untracked frames stay NaN.
  double lowest = std::numeric_limits<double>::infinity(), highest = -lowest;
  for (double v : scale_by.empty() ? values : scale_by)
    if (std::isfinite(v)) lowest = std::min(lowest, v), highest = std::max(highest, v);
  std::vector<double> scaled(values.size(), kNaN);
  for (int f = 0; f < n; ++f)
    if (std::isfinite(values[f])) scaled[f] = highest > lowest ? (values[f] - lowest) / (highest - lowest) : 0.0;

  ClosureMetric m;
  std::vector<double> speech;
  for (const WordFrames& w : words) {
    if (!w.silence)
      for (int f = std::max(w.first, 0); f <= std::min(w.last, n - 1); ++f)
        if (!std::isnan(scaled[f])) speech.push_back(scaled[f]);
    if (!is_bilabial_word(w.word)) continue;
    WordClosure closure{std::string(w.word), w.first, w.last, kNaN, false, w.last < 0 || w.first > n - 1};
    if (!closure.outside) {
      for (int f = std::max(w.first - widening, 0); f <= std::min(w.last + widening, n - 1); ++f)
        if (!std::isnan(scaled[f]))
          closure.minimum = std::isnan(closure.minimum) ? scaled[f] : std::min(closure.minimum, scaled[f]);
      closure.closed = closure.minimum <= ClosureMetric::kClosureLevel;
      ++m.bilabial_words;
      m.closures_seen += closure.closed;
    }
    m.words.push_back(std::move(closure));
  }
  m.opening = quantile(speech, 0.9);

  m.silence_median = m.silence_jitter = kNaN;
  // The final silence is the last word, when it is a silence: one earlier (the opening
  // silence, a pause) is not where the mouth comes to rest at the end.
  if (words.empty() || !words.back().silence) return m;
  const WordFrames& final_silence = words.back();
  std::vector<double> silence;
  double steps = 0;
  int step_count = 0;
  const int first = std::max(final_silence.first + silence_delay, 0);
  const int last = std::min(final_silence.last, n - 1);
  for (int f = first; f <= last; ++f) {
    if (std::isnan(scaled[f])) continue;
    silence.push_back(scaled[f]);
    if (f > first && !std::isnan(scaled[f - 1])) steps += std::abs(scaled[f] - scaled[f - 1]), ++step_count;
  }
  m.silence_median = median(silence);
  if (step_count > 0) m.silence_jitter = steps / step_count;
  return m;
}

SpeechAgreement speech_agreement(std::span<const double> truth, std::span<const double> output,
                                 const std::vector<bool>& speech, int final_silence_first, int final_silence_last) {
  if (truth.size() != output.size() || truth.size() != speech.size())
    throw std::invalid_argument("speech_agreement: the series differ in length");
  std::vector<double> spoken_truth, spoken_output;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (!speech[i]) continue;
    spoken_truth.push_back(truth[i]);
    spoken_output.push_back(output[i]);
  }
  const SeriesAgreement spoken = compare_series(spoken_truth, spoken_output);
  SpeechAgreement result;
  result.speech_frames = spoken.pairs_used;
  result.pearson_r = spoken.pearson_r;
  result.std_ratio = spoken.std_ratio;

  std::vector<double> silent_truth, silent_output, all_truth;
  for (double v : truth)
    if (std::isfinite(v)) all_truth.push_back(v);
  const int last = std::min(final_silence_last, static_cast<int>(truth.size()) - 1);
  for (int f = std::max(final_silence_first, 0); f <= last; ++f) {
    const auto i = static_cast<std::size_t>(f);
    if (std::isnan(truth[i]) || std::isnan(output[i])) continue;
    silent_truth.push_back(truth[i]);
    silent_output.push_back(output[i]);
  }
  result.silence_distance = kNaN;
  if (!silent_truth.empty() && !all_truth.empty()) {
    const auto [lowest, highest] = std::minmax_element(all_truth.begin(), all_truth.end());
    const double range = *highest - *lowest;
    if (range > 0) result.silence_distance = std::abs(median(silent_output) - median(silent_truth)) / range;
  }
  return result;
}

}  // namespace lipdrive
