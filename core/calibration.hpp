// Performer calibration (docs/method.md 4, "Calibration"): per-measure ranges that map
// this performer's mouth onto drive signals in [0, 1].
#pragma once

#include "core/drive_signals.hpp"
#include "core/facial_indices.hpp"
#include "core/mouth_measures.hpp"

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>

namespace lipdrive {

struct MeasureRange {
  double min = 0, max = 1;  // the measure at rest / at its extreme; min > max is allowed (inverted)
  /// (value - min) / (max - min), clamped to [0, 1].
  double scale(double value) const;
};

/// The three calibrated measures of one frame.
struct CalibrationSample {
  double open = 0;        // MouthMeasures::open
  double width = 0;       // MouthMeasures::width_fit
  double protrusion = 0;  // MouthMeasures::protrusion_3d
};
CalibrationSample calibration_sample(const MouthMeasures& measures);

/// The performer's face in a model with expression shapes (the ICT head): the identity
/// coefficients fit_identity() finds over the neutral frames of a calibration, frozen for every
/// frame after. They belong to one model: `model_fingerprint` is its identity_fingerprint()
/// (core/model_format.hpp), and another model ignores them. Fixed size, so a profile stays
/// trivially copyable (the daemon publishes it between threads).
struct PerformerIdentity {
  std::uint32_t model_fingerprint = 0;
  int components = 0;                            // coefficients in use, at most kMaxFitComponents
  std::array<float, kMaxFitComponents> alpha{};  // in units of each component's stddev
  /// The performer's rest point (fit_rest_expression): the fit's expression weights on the
  /// neutral frames, in the model's order; every frame's weights leave relative to it
  /// (above_rest). `expressions` = how many are set (0: none, the weights as fitted).
  int expressions = 0;
  std::array<float, kMaxFitExpressions> rest{};
  /// The coefficients as the Fitter takes them, `model_components` long (zero past `components`).
  Eigen::VectorXf vector(int model_components) const;
  /// The rest point as above_rest takes it (zero past `expressions`).
  FitOutput::Expressions rest_weights() const;
};

/// The ranges of one performer. The defaults, for a performer not yet calibrated, span what
/// `lipdrive process` measures on the GRID takes and the generated talking face: closed to
/// wide-open lips, rounded to spread, and the fit's protrusion range.
struct PerformerProfile {
  MeasureRange open{0.03, 0.35};            // MouthMeasures::open
  MeasureRange width{1.0, 1.8};             // MouthMeasures::width_fit
  MeasureRange protrusion{-0.02, 0.18};     // MouthMeasures::protrusion_3d
  MeasureRange protrusion_side{0.0, 0.12};  // the side camera's, over the nose length (rest = 0)
  CalibrationSample rest{0.03, 1.3, 0.0};   // the neutral capture's median
  bool calibrated = false;                  // measured on this performer (else the defaults)
  /// docs/method.md 6 indices of the performer's neutral face, when the calibration saw one.
  std::optional<std::array<double, kNumFacialIndices>> face_indices;
  /// The performer's identity, when the calibration fitted one (a model with expression shapes).
  std::optional<PerformerIdentity> identity;
};

/// A capture that cannot calibrate: too few frames, or a range of motion without motion.
class CalibrationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Collects one capture (neutral or range of motion) in fixed storage: add() allocates
/// nothing, so the daemon can capture on its processing thread.
class CalibrationCapture {
 public:
  static constexpr int kCapacity = 3600;  // a minute at 60 fps; later samples are ignored
  /// Keeps the frame's measures; a frame with one that is not a number is left out.
  void add(const MouthMeasures& measures);
  void clear() { count_ = 0; }
  int size() const { return count_; }
  std::span<const CalibrationSample> samples() const { return {samples_.data(), static_cast<std::size_t>(count_)}; }

 private:
  std::array<CalibrationSample, kCapacity> samples_{};
  int count_ = 0;
};

/// The fewest frames a neutral capture needs (a third of a second at 30 fps).
inline constexpr int kMinNeutralFrames = 10;

/// A profile from a neutral capture (the performer at rest) and a range-of-motion capture
/// (open / wide / round / closed). Robust statistics so that a few mistracked frames do not
/// move the ends (quantiles by the rank rule of core/statistics.hpp): rest = median of the
/// neutral frames; open and protrusion run from rest to the 98th percentile of the motion,
/// width from its 2nd to its 98th percentile (rounding narrows the mouth below rest). Throws
/// CalibrationError naming the measure at fault.
PerformerProfile calibrate(std::span<const CalibrationSample> neutral, std::span<const CalibrationSample> motion);

/// Re-centring on a new neutral capture: each range keeps its span and moves with the rest
/// point, which also removes the slow drift of a helmet slipping during a take.
PerformerProfile recentre(const PerformerProfile& profile, std::span<const CalibrationSample> neutral);

/// The drive signals of one tracked frame: calibrated open / width / protrusion, seal as
/// measured, viseme weights as given, tracking = 1.
DriveSignals drive_signals(const MouthMeasures& measures, std::span<const float> viseme_weights,
                           const PerformerProfile& profile);

}  // namespace lipdrive
