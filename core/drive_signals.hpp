// The values that leave the measuring part of the pipeline for the drive side (docs/data-flow.md):
// one float per signal, in [0, 1] once calibrated, on fixed-size storage.
#pragma once

#include "core/arkit.hpp"

#include <array>
#include <optional>
#include <span>
#include <string_view>

namespace lipdrive {

// The 16 visemes of docs/method.md 2, in this order (the order of the viseme signals too).
inline constexpr std::array<std::string_view, 16> kVisemeNames{
    "Aah", "BigAah", "B-M-P", "Ch-J-Sh", "D-S-T", "Eee", "Eh", "F-V", "i", "K", "N", "Oh", "Ooh-Q", "R", "Th", "W"};
inline constexpr int kNumVisemes = static_cast<int>(kVisemeNames.size());

/// What a drive channel can follow. kTracking is 1 while a face is tracked, else 0; kSeal is
/// the probability that the lips touch (core/lip_contact.hpp), not calibrated. After the
/// measures come the 16 viseme weights, then the 52 ARKit weights (core/arkit.hpp).
enum class Signal : int { kOpen, kWidth, kProtrusion, kTracking, kSeal, kFirstViseme };
inline constexpr int kFirstArkitSignal = static_cast<int>(Signal::kFirstViseme) + kNumVisemes;
inline constexpr int kNumSignals = kFirstArkitSignal + kNumArkit;

inline constexpr Signal viseme_signal(int viseme) {
  return static_cast<Signal>(static_cast<int>(Signal::kFirstViseme) + viseme);
}
/// The signal of kArkitNames[a].
inline constexpr Signal arkit_signal(int a) { return static_cast<Signal>(kFirstArkitSignal + a); }

/// "open", "width", "protrusion", "tracking", "seal", "viseme_Aah" ... "viseme_W",
/// "arkit_eyeBlinkLeft" ... "arkit_tongueOut".
std::string_view signal_name(Signal signal);
std::optional<Signal> parse_signal(std::string_view name);

struct DriveSignals {
  std::array<float, kNumSignals> values{};
  float& operator[](Signal s) { return values[static_cast<int>(s)]; }
  float operator[](Signal s) const { return values[static_cast<int>(s)]; }
  /// The 52 ARKit weights, in the order of kArkitNames.
  std::span<const float, kNumArkit> arkit() const {
    return std::span<const float, kNumArkit>(values.data() + kFirstArkitSignal, kNumArkit);
  }
};

}  // namespace lipdrive
