#include "core/calibration.hpp"

#include "core/statistics.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace lipdrive {

double MeasureRange::scale(double value) const {
  if (max == min) return 0;
  return std::clamp((value - min) / (max - min), 0.0, 1.0);
}

Eigen::VectorXf PerformerIdentity::vector(int model_components) const {
  Eigen::VectorXf coefficients = Eigen::VectorXf::Zero(model_components);
  const int n = std::min({components, model_components, kMaxFitComponents});
  for (int i = 0; i < n; ++i) coefficients[i] = alpha[static_cast<std::size_t>(i)];
  return coefficients;
}

FitOutput::Expressions PerformerIdentity::rest_weights() const {
  FitOutput::Expressions weights = FitOutput::Expressions::Zero();
  for (int e = 0; e < std::min(expressions, kMaxFitExpressions); ++e) weights[e] = rest[static_cast<std::size_t>(e)];
  return weights;
}

CalibrationSample calibration_sample(const MouthMeasures& measures) {
  return {measures.open, measures.width_fit, measures.protrusion_3d};
}

void CalibrationCapture::add(const MouthMeasures& measures) {
  const CalibrationSample sample = calibration_sample(measures);
  if (!std::isfinite(sample.open) || !std::isfinite(sample.width) || !std::isfinite(sample.protrusion)) return;
  if (count_ < kCapacity) samples_[static_cast<std::size_t>(count_++)] = sample;
}

namespace {

/// The p-quantile (core/statistics.hpp) of one measure over the samples.
double quantile(std::span<const CalibrationSample> samples, double CalibrationSample::*measure, double p) {
  std::vector<double> values;
  values.reserve(samples.size());
  for (const CalibrationSample& s : samples) values.push_back(s.*measure);
  return lipdrive::quantile(values, p);
}

CalibrationSample median(std::span<const CalibrationSample> neutral) {
  if (neutral.size() < static_cast<std::size_t>(kMinNeutralFrames))
    throw CalibrationError("the neutral capture has " + std::to_string(neutral.size()) + " tracked frames, needs " +
                           std::to_string(kMinNeutralFrames));
  return {quantile(neutral, &CalibrationSample::open, 0.5), quantile(neutral, &CalibrationSample::width, 0.5),
          quantile(neutral, &CalibrationSample::protrusion, 0.5)};
}

// Spans below these (in units of d, the eye-to-nose-tip distance) mean the performer did not
// move that part of the mouth during the range-of-motion capture.
constexpr double kMinOpenSpan = 0.05, kMinWidthSpan = 0.03, kMinProtrusionSpan = 0.005;

void require_span(const MeasureRange& range, double min_span, const char* what, const char* how) {
  if (!(range.max - range.min >= min_span))  // NaN included
    throw CalibrationError(std::string("the range of motion shows no ") + what + " (" +
                           std::to_string(range.max - range.min) + " of d): " + how);
}

}  // namespace

PerformerProfile calibrate(std::span<const CalibrationSample> neutral, std::span<const CalibrationSample> motion) {
  PerformerProfile profile;
  profile.rest = median(neutral);
  if (motion.size() < static_cast<std::size_t>(kMinNeutralFrames))
    throw CalibrationError("the range-of-motion capture has " + std::to_string(motion.size()) + " tracked frames");
  profile.open = {profile.rest.open, quantile(motion, &CalibrationSample::open, 0.98)};
  profile.width = {quantile(motion, &CalibrationSample::width, 0.02),
                   quantile(motion, &CalibrationSample::width, 0.98)};
  profile.protrusion = {profile.rest.protrusion, quantile(motion, &CalibrationSample::protrusion, 0.98)};
  require_span(profile.open, kMinOpenSpan, "mouth opening", "open the mouth wide");
  require_span(profile.width, kMinWidthSpan, "change of mouth width", "smile wide and round the lips");
  // Some performers barely protrude; a flat range would amplify noise, so it gets a floor.
  profile.protrusion.max = std::max(profile.protrusion.max, profile.protrusion.min + kMinProtrusionSpan);
  profile.calibrated = true;
  return profile;
}

PerformerProfile recentre(const PerformerProfile& profile, std::span<const CalibrationSample> neutral) {
  const CalibrationSample rest = median(neutral);
  PerformerProfile moved = profile;
  const auto shift = [](MeasureRange& range, double by) {
    range.min += by;
    range.max += by;
  };
  shift(moved.open, rest.open - profile.rest.open);
  shift(moved.width, rest.width - profile.rest.width);
  shift(moved.protrusion, rest.protrusion - profile.rest.protrusion);
  moved.rest = rest;
  moved.calibrated = true;
  return moved;
}

DriveSignals drive_signals(const MouthMeasures& measures, std::span<const float> viseme_weights,
                           const PerformerProfile& profile) {
  DriveSignals s;
  s[Signal::kOpen] = static_cast<float>(profile.open.scale(measures.open));
  s[Signal::kWidth] = static_cast<float>(profile.width.scale(measures.width_fit));
  s[Signal::kProtrusion] = static_cast<float>(profile.protrusion.scale(measures.protrusion_3d));
  s[Signal::kTracking] = 1;
  s[Signal::kSeal] = static_cast<float>(measures.seal);
  for (std::size_t v = 0; v < viseme_weights.size() && v < static_cast<std::size_t>(kNumVisemes); ++v)
    s[viseme_signal(static_cast<int>(v))] = viseme_weights[v];
  return s;
}

}  // namespace lipdrive
