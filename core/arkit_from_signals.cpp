#include "core/arkit_from_signals.hpp"

#include <algorithm>

namespace lipdrive {
namespace {

float unit(float value) { return std::clamp(value, 0.0f, 1.0f); }

}  // namespace

DerivedArkitWeights arkit_from_signals(const DriveSignals& signals) {
  const float open = unit(signals[Signal::kOpen]);
  const float protrusion = unit(signals[Signal::kProtrusion]);
  return {open, unit(signals[Signal::kSeal]), protrusion * open, protrusion * (1 - open)};
}

}  // namespace lipdrive
