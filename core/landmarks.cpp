#include "core/landmarks.hpp"

namespace lipdrive {
namespace {

// Each set adds one region to the previous one (docs/method.md 1).
constexpr std::array<int, kNumLandmarks> make_order() {
  std::array<int, kNumLandmarks> order{};
  int n = 0;
  for (int i = 48; i <= 67; ++i) order[n++] = i;  // F1: lips
  for (int i = 27; i <= 35; ++i) order[n++] = i;  // F2: + nose
  for (int i = 36; i <= 47; ++i) order[n++] = i;  // F3: + eyes
  for (int i = 17; i <= 26; ++i) order[n++] = i;  // F4: + eyebrows
  for (int i = 0; i <= 16; ++i) order[n++] = i;   // F5: + jaw contour
  return order;
}

template <LandmarkSet S>
constexpr auto sorted_set() {
  constexpr auto order = make_order();
  std::array<int, landmark_count(S)> set{};
  for (int i = 0; i < landmark_count(S); ++i) set[i] = order[i];
  for (std::size_t i = 1; i < set.size(); ++i)  // insertion sort (constexpr)
    for (std::size_t j = i; j > 0 && set[j - 1] > set[j]; --j) std::swap(set[j - 1], set[j]);
  return set;
}

constexpr auto kF1 = sorted_set<LandmarkSet::F1>();
constexpr auto kF2 = sorted_set<LandmarkSet::F2>();
constexpr auto kF3 = sorted_set<LandmarkSet::F3>();
constexpr auto kF4 = sorted_set<LandmarkSet::F4>();
constexpr auto kF5 = sorted_set<LandmarkSet::F5>();

}  // namespace

std::span<const int> landmark_indices(LandmarkSet set) {
  switch (set) {
    case LandmarkSet::F1: return kF1;
    case LandmarkSet::F2: return kF2;
    case LandmarkSet::F3: return kF3;
    case LandmarkSet::F4: return kF4;
    case LandmarkSet::F5: return kF5;
  }
  return {};
}

std::optional<LandmarkSet> parse_landmark_set(std::string_view name) {
  for (std::size_t i = 0; i < kLandmarkSetNames.size(); ++i)
    if (kLandmarkSetNames[i] == name) return static_cast<LandmarkSet>(i);
  return std::nullopt;
}

std::string_view landmark_set_name(LandmarkSet set) { return kLandmarkSetNames[static_cast<std::size_t>(set)]; }

}  // namespace lipdrive
