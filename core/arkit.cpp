#include "core/arkit.hpp"

#include "core/drive_signals.hpp"
#include "core/fitting.hpp"

#include <algorithm>
#include <stdexcept>

namespace lipdrive {
namespace {

float unit(double value) { return static_cast<float>(std::clamp(value, 0.0, 1.0)); }

}  // namespace

std::optional<int> arkit_index_of_expression(std::string_view expression_name) {
  for (const auto& [suffix, side] : {std::pair{"_L", "Left"}, std::pair{"_R", "Right"}}) {
    if (!expression_name.ends_with(suffix)) continue;
    const std::string_view base = expression_name.substr(0, expression_name.size() - 2);
    if (const auto sided = arkit_index(std::string(base) + side)) return sided;
    return arkit_index(base);  // a half of a shape Apple does not split
  }
  return arkit_index(expression_name);
}

ArkitMap::ArkitMap(std::span<const std::string> expression_names) : from_fit_(!expression_names.empty()) {
  for (auto& s : sources_) s = {-1, -1};
  std::array<bool, kNumArkit> split{};  // the name's shapes are halves
  for (std::size_t e = 0; e < expression_names.size(); ++e) {
    const std::string& name = expression_names[e];
    const auto index = arkit_index_of_expression(name);
    if (!index) continue;
    const auto a = static_cast<std::size_t>(*index);
    const std::string_view apple = kArkitNames[a];
    const bool half = name != apple && !apple.ends_with("Left") && !apple.ends_with("Right");
    const int slot = half && name.ends_with("_R") ? 1 : 0;
    if (sources_[a][slot] >= 0 || (split[a] != half && sources_[a] != std::array{-1, -1}))
      throw std::invalid_argument("ARKit map: expression \"" + name + "\" and another both stand for " +
                                  std::string(apple));
    sources_[a][slot] = static_cast<int>(e);
    split[a] = half;
  }
  for (int a = 0; a < kNumArkit; ++a) {
    std::array<int, 2>& s = sources_[static_cast<std::size_t>(a)];
    const std::string_view apple = kArkitNames[static_cast<std::size_t>(a)];
    if (split[static_cast<std::size_t>(a)] && (s[0] < 0 || s[1] < 0))
      throw std::invalid_argument("ARKit map: " + std::string(apple) + " has only one of its halves _L and _R");
    if (is_unobservable_expression(apple)) s = {-1, -1};
  }
}

void ArkitMap::from_expressions(std::span<const double> expressions, std::span<float, kNumArkit> out) const {
  for (int a = 0; a < kNumArkit; ++a) {
    const auto [first, second] = sources(a);
    const double weight = first < 0    ? 0.0
                          : second < 0 ? expressions[static_cast<std::size_t>(first)]
                                       : (expressions[static_cast<std::size_t>(first)] +
                                          expressions[static_cast<std::size_t>(second)]) / 2;
    out[static_cast<std::size_t>(a)] = unit(weight);
  }
}

void set_arkit_signals(const ArkitMap& map, std::span<const double> expressions, DriveSignals& signals) {
  static constexpr int kJawOpen = *arkit_index("jawOpen"), kMouthClose = *arkit_index("mouthClose"),
                       kMouthFunnel = *arkit_index("mouthFunnel"), kMouthPucker = *arkit_index("mouthPucker");
  if (map.from_fit()) {
    map.from_expressions(expressions,
                         std::span<float, kNumArkit>(signals.values.data() + kFirstArkitSignal, kNumArkit));
    float& close = signals[arkit_signal(kMouthClose)];
    close = std::max(close, unit(signals[Signal::kSeal]) * signals[arkit_signal(kJawOpen)]);
    return;
  }
  const float open = unit(signals[Signal::kOpen]);
  const float protrusion = unit(signals[Signal::kProtrusion]);
  for (int a = 0; a < kNumArkit; ++a) signals[arkit_signal(a)] = 0;
  signals[arkit_signal(kJawOpen)] = open;
  signals[arkit_signal(kMouthClose)] = unit(signals[Signal::kSeal]);
  signals[arkit_signal(kMouthFunnel)] = protrusion * open;
  signals[arkit_signal(kMouthPucker)] = protrusion * (1 - open);
}

}  // namespace lipdrive
