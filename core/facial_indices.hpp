// Facial indices of a neutral face (docs/method.md 6): 13 anthropometric distances and 12
// indices (smaller distance / larger distance × 100, after Farkas' craniofacial norms), and
// the performer ↔ model compatibility check built on the two mouth indices.
//
// Anthropometric points on the iBUG 68 landmarks (0-based). The landmarks only approximate
// the soft-tissue points; where no landmark sits on a point, the nearest one that dlib
// tracks stably is taken:
//   n   nasion             27  top of the nose bridge
//   gn  gnathion           8   chin tip, lowest jaw-contour point
//   zy  zygion             0 / 16  jaw-contour extremes at ear level (the widest face points
//                                   the 68 landmarks have; the real zygion lies higher)
//   go  gonion             4 / 12  jaw-contour angle
//   sn  subnasale          33  nose base, midline
//   al  alare              31 / 35 nostril wings
//   ex  exocanthion        36 / 45 outer eye corners
//   en  endocanthion       39 / 42 inner eye corners
//   ch  cheilion           48 / 54 outer mouth corners
//   ls  labiale superius   51  upper-lip vermilion border, midline
//   li  labiale inferius   57  lower-lip vermilion border, midline
#pragma once

#include "core/landmarks.hpp"
#include "core/morphable_model.hpp"

#include <array>
#include <string_view>

namespace lipdrive {

inline constexpr int kNumFacialDistances = 13;
inline constexpr int kNumFacialIndices = 12;

struct FacialDistanceDefinition {
  std::string_view name;
  int from, to;  // iBUG landmarks
};

/// The 13 distances, in this order.
inline constexpr std::array<FacialDistanceDefinition, kNumFacialDistances> kFacialDistances{{
    {"n-gn", 27, 8},    // 0  morphological face height
    {"zy-zy", 0, 16},   // 1  face width
    {"go-go", 4, 12},   // 2  mandible width
    {"n-sn", 27, 33},   // 3  nose height
    {"sn-gn", 33, 8},   // 4  lower face height
    {"al-al", 31, 35},  // 5  nose width
    {"ex-ex", 36, 45},  // 6  biocular width
    {"en-en", 39, 42},  // 7  intercanthal width
    {"ex-en", 36, 39},  // 8  eye fissure length (the subject's right eye)
    {"ch-ch", 48, 54},  // 9  mouth width
    {"ls-li", 51, 57},  // 10 vertical lip height
    {"sn-ls", 33, 51},  // 11 upper lip (philtrum) height
    {"li-gn", 57, 8},   // 12 chin height
}};

struct FacialIndexDefinition {
  std::string_view name;
  int smaller, larger;  // positions in kFacialDistances: index = 100 · smaller / larger
};

/// The 12 indices, in this order.
inline constexpr std::array<FacialIndexDefinition, kNumFacialIndices> kFacialIndices{{
    {"facial", 0, 1},                  // n-gn / zy-zy
    {"mandible_face_width", 2, 1},     // go-go / zy-zy
    {"nose_face_height", 3, 0},        // n-sn / n-gn
    {"lower_face_face_height", 4, 0},  // sn-gn / n-gn
    {"nasal", 5, 3},                   // al-al / n-sn
    {"intercanthal", 7, 6},            // en-en / ex-ex
    {"eye_fissure", 8, 6},             // ex-en / ex-ex
    {"mouth_width", 9, 6},             // ch-ch / ex-ex (docs/method.md 6)
    {"vertical_mouth_height", 10, 0},  // ls-li / n-gn (docs/method.md 6)
    {"nose_mouth_width", 5, 9},        // al-al / ch-ch
    {"upper_lip_lower_face", 11, 4},   // sn-ls / sn-gn
    {"chin_lower_face", 12, 4},        // li-gn / sn-gn
}};
inline constexpr int kMouthWidthIndex = 7;
inline constexpr int kVerticalMouthHeightIndex = 8;

struct FacialMeasures {
  std::array<double, kNumFacialDistances> distances{};  // landmark units (px or mm)
  std::array<double, kNumFacialIndices> indices{};      // dimensionless × 100
};

/// docs/method.md 6 on the 68 landmarks of a frontal, neutral face.
FacialMeasures facial_measures(const Landmarks2D& landmarks);

/// The model's neutral landmarks (pose "neutral", else the mean) seen from the front: model
/// x and y (z dropped), so that they compare with a performer's frontal camera frame.
/// Throws std::invalid_argument when a landmark of kFacialDistances is unmapped.
Landmarks2D frontal_neutral_landmarks(const MorphableModel& model);

enum class IndexClass { kLow, kMiddle, kHigh };
std::string_view index_class_name(IndexClass c);  // "low", "middle", "high"

/// Reference-corpus ranges: low < low_below <= middle <= high_above < high.
struct ClassThresholds {
  double low_below, high_above;
};
inline constexpr ClassThresholds kVerticalMouthHeightClasses{13.58, 16.22};  // docs/method.md 6
inline constexpr ClassThresholds kMouthWidthClasses{49.18, 54.80};           // docs/method.md 6

IndexClass classify(double index, ClassThresholds thresholds);

/// The classes docs/method.md 6 documents ranges for (the other indices have none).
struct MouthClasses {
  IndexClass vertical_mouth_height, mouth_width;
};
MouthClasses mouth_classes(const FacialMeasures& measures);

struct Compatibility {
  MouthClasses performer, model;
  /// Vertical mouth height two classes apart (low performer on a high head, or the
  /// reverse): docs/method.md 6 reports clearly worse lips then.
  bool warn = false;
};
Compatibility compatibility(const FacialMeasures& performer, const FacialMeasures& model);

}  // namespace lipdrive
