// Performer calibration (DESIGN.md 4.4 "Scaled", 2 "Calibration"): per-measure ranges that map
// this performer's mouth onto drive signals in [0, 1].
#pragma once

#include "core/drive_signals.hpp"
#include "core/mouth_measures.hpp"

#include <span>

namespace lipdrive {

struct MeasureRange {
  double min = 0, max = 1;  // the measure at rest / at its extreme; min > max is allowed (inverted)
  /// (value - min) / (max - min), clamped to [0, 1].
  double scale(double value) const;
};

/// The ranges of one performer. The defaults cover an average face on the default model
/// before any calibration: closed to wide-open lips, rest width to a broad smile, and the
/// model's rounded visemes for protrusion.
struct PerformerProfile {
  MeasureRange open{0.0, 0.5};          // MouthMeasures::height_fit
  MeasureRange width{0.6, 1.1};         // MouthMeasures::width_fit
  MeasureRange protrusion{0.0, 0.06};   // MouthMeasures::protrusion_3d
  bool calibrated = false;              // measured on this performer (else the defaults)
};

/// The drive signals of one tracked frame: calibrated open / width / protrusion, viseme
/// weights as given, tracking = 1.
DriveSignals drive_signals(const MouthMeasures& measures, std::span<const float> viseme_weights,
                           const PerformerProfile& profile);

}  // namespace lipdrive
