// ARKit blendshape weights derived from the drive signals: the stand-in for a fit of
// ARKit-named expression shapes (DESIGN.md 4.10), which yields the weights directly. Only
// the four mouth weights the signals can speak for are derived; replace this file as a
// whole once the fit provides them.
//
//   jawOpen     = open                         the lips' opening
//   mouthClose  = seal                         the lips touch (lip contact from the pixels)
//   mouthFunnel = protrusion · open            lips pushed forward and apart ("oh")
//   mouthPucker = protrusion · (1 − open)      lips pushed forward and together ("oo", a kiss)
//
// All in [0, 1]; funnel + pucker = protrusion.
#pragma once

#include "core/drive_signals.hpp"

#include <array>
#include <string_view>

namespace lipdrive {

inline constexpr std::array<std::string_view, 4> kDerivedArkitNames{"jawOpen", "mouthClose", "mouthFunnel",
                                                                    "mouthPucker"};

/// Weights in the order of kDerivedArkitNames.
using DerivedArkitWeights = std::array<float, kDerivedArkitNames.size()>;

DerivedArkitWeights arkit_from_signals(const DriveSignals& signals);

}  // namespace lipdrive
