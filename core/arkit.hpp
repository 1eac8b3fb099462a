// ARKit blendshape weights (docs/arkit.md): Apple's 52 names in Apple's order, the map from a
// model's expression shapes to them, and the one place that makes a frame's 52 weights.
//
// A model with expression shapes (the ICT head) gives them from the fit: each Apple name takes
// the weight of the shape of the same name, ICT's `_L`/`_R` becoming `Left`/`Right` (the face's
// own left and right, as Apple's names mean); the two halves of a shape Apple does not split
// (`browInnerUp_L` + `browInnerUp_R`, `cheekPuff_L` + `cheekPuff_R`) give the mean of their
// weights. The shapes a 68-point fit cannot observe (is_unobservable_expression: eye gaze,
// cheekPuff, tongueOut) are held at 0, and so is a name without a shape (ICT has no tongueOut).
//
// A model without expression shapes (pose-PCA models) gives the four mouth weights the drive
// signals speak for, and the other 48 read 0:
//   jawOpen     = open                         the lips' opening
//   mouthClose  = seal                         the lips touch (lip contact from the pixels)
//   mouthFunnel = protrusion · open            lips pushed forward and apart ("oh")
//   mouthPucker = protrusion · (1 − open)      lips pushed forward and together ("oo", a kiss)
#pragma once

#include <array>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace lipdrive {

struct DriveSignals;

/// Apple's ARFaceAnchor.BlendShapeLocation names in the order of Apple's documentation (left
/// eye, right eye, mouth and jaw, eyebrows, cheeks, nose, tongue), which is also the order of
/// Live Link Face's recordings.
inline constexpr std::array<std::string_view, 52> kArkitNames{
    "eyeBlinkLeft",     "eyeLookDownLeft",   "eyeLookInLeft",      "eyeLookOutLeft",      "eyeLookUpLeft",
    "eyeSquintLeft",    "eyeWideLeft",       "eyeBlinkRight",      "eyeLookDownRight",    "eyeLookInRight",
    "eyeLookOutRight",  "eyeLookUpRight",    "eyeSquintRight",     "eyeWideRight",        "jawForward",
    "jawLeft",          "jawRight",          "jawOpen",            "mouthClose",          "mouthFunnel",
    "mouthPucker",      "mouthLeft",         "mouthRight",         "mouthSmileLeft",      "mouthSmileRight",
    "mouthFrownLeft",   "mouthFrownRight",   "mouthDimpleLeft",    "mouthDimpleRight",    "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower",   "mouthRollUpper",     "mouthShrugLower",     "mouthShrugUpper",
    "mouthPressLeft",   "mouthPressRight",   "mouthLowerDownLeft", "mouthLowerDownRight", "mouthUpperUpLeft",
    "mouthUpperUpRight", "browDownLeft",     "browDownRight",      "browInnerUp",         "browOuterUpLeft",
    "browOuterUpRight", "cheekPuff",         "cheekSquintLeft",    "cheekSquintRight",    "noseSneerLeft",
    "noseSneerRight",   "tongueOut"};
inline constexpr int kNumArkit = static_cast<int>(kArkitNames.size());

/// One frame's 52 weights in the order of kArkitNames.
using ArkitWeights = std::array<float, kNumArkit>;

/// The index of an Apple name in kArkitNames; nullopt for another name.
constexpr std::optional<int> arkit_index(std::string_view name) {
  for (int a = 0; a < kNumArkit; ++a)
    if (kArkitNames[static_cast<std::size_t>(a)] == name) return a;
  return std::nullopt;
}

/// The Apple name an expression shape of a model stands for: its own name, `_L`/`_R` made
/// `Left`/`Right`, or the whole shape's name for a half Apple does not split (`browInnerUp_L`).
/// nullopt: no ARKit shape.
std::optional<int> arkit_index_of_expression(std::string_view expression_name);

/// Which of a model's expression shapes make each ARKit weight, precomputed once per model.
class ArkitMap {
 public:
  /// `expression_names`: the model's (MorphableModel::expression_names), empty for a pose-PCA
  /// model. Names that are no ARKit shape are ignored. Throws std::invalid_argument when two
  /// shapes claim one Apple name, or a split shape lacks one of its halves.
  explicit ArkitMap(std::span<const std::string> expression_names);

  /// True when the weights come from the fit (the model has expression shapes).
  bool from_fit() const { return from_fit_; }

  /// The expression shapes behind Apple name `a`: none (-1, -1), one (e, -1) or two halves
  /// (l, r) merged by their mean. None for the shapes held at 0.
  std::array<int, 2> sources(int a) const { return sources_[static_cast<std::size_t>(a)]; }

  /// The 52 weights of a fit, each in [0, 1]: `expressions` are the fit's weights in the model's
  /// order (FitOutput::expressions). Only for a map from_fit(). Allocates nothing.
  void from_expressions(std::span<const double> expressions, std::span<float, kNumArkit> out) const;

 private:
  std::array<std::array<int, 2>, kNumArkit> sources_;
  bool from_fit_;
};

/// Writes the 52 ARKit signals of a tracked frame into `signals` (core/drive_signals.hpp), from
/// `expressions` (the fit's weights in the model's order, FitOutput::expressions) when the map
/// comes from a model with expression shapes, else from the open, seal and protrusion signals
/// already in `signals`. Either way lips that touch are closed: from the fit, mouthClose is at
/// least seal × jawOpen, which is what ARKit's mouthClose means (the lips together over an
/// open jaw); lips pressed together can read apart in the landmarks, and the fit then opens
/// the jaw to match them. Allocates nothing.
void set_arkit_signals(const ArkitMap& map, std::span<const double> expressions, DriveSignals& signals);

}  // namespace lipdrive
