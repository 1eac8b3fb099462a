#include "core/calibration.hpp"

#include <algorithm>

namespace lipdrive {

double MeasureRange::scale(double value) const {
  if (max == min) return 0;
  return std::clamp((value - min) / (max - min), 0.0, 1.0);
}

DriveSignals drive_signals(const MouthMeasures& measures, std::span<const float> viseme_weights,
                           const PerformerProfile& profile) {
  DriveSignals s;
  s[Signal::kOpen] = static_cast<float>(profile.open.scale(measures.height_fit));
  s[Signal::kWidth] = static_cast<float>(profile.width.scale(measures.width_fit));
  s[Signal::kProtrusion] = static_cast<float>(profile.protrusion.scale(measures.protrusion_3d));
  s[Signal::kTracking] = 1;
  for (std::size_t v = 0; v < viseme_weights.size() && v < static_cast<std::size_t>(kNumVisemes); ++v)
    s[viseme_signal(static_cast<int>(v))] = viseme_weights[v];
  return s;
}

}  // namespace lipdrive
