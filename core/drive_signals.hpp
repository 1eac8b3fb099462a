// The values that leave the measuring part of the pipeline for the drive side (docs/data-flow.md):
// one float per signal, in [0, 1] once calibrated, on fixed-size storage.
#pragma once

#include <array>
#include <optional>
#include <string_view>

namespace lipdrive {

// The 16 visemes of docs/method.md 2, in this order (the order of the viseme signals too).
inline constexpr std::array<std::string_view, 16> kVisemeNames{
    "Aah", "BigAah", "B-M-P", "Ch-J-Sh", "D-S-T", "Eee", "Eh", "F-V", "i", "K", "N", "Oh", "Ooh-Q", "R", "Th", "W"};
inline constexpr int kNumVisemes = static_cast<int>(kVisemeNames.size());

/// What a drive channel can follow. kTracking is 1 while a face is tracked, else 0; kSeal is
/// the probability that the lips touch (core/lip_contact.hpp), not calibrated.
enum class Signal : int { kOpen, kWidth, kProtrusion, kTracking, kSeal, kFirstViseme };
inline constexpr int kNumSignals = static_cast<int>(Signal::kFirstViseme) + kNumVisemes;

inline constexpr Signal viseme_signal(int viseme) {
  return static_cast<Signal>(static_cast<int>(Signal::kFirstViseme) + viseme);
}

/// "open", "width", "protrusion", "tracking", "seal", "viseme_Aah" ... "viseme_W".
std::string_view signal_name(Signal signal);
std::optional<Signal> parse_signal(std::string_view name);

struct DriveSignals {
  std::array<float, kNumSignals> values{};
  float& operator[](Signal s) { return values[static_cast<int>(s)]; }
  float operator[](Signal s) const { return values[static_cast<int>(s)]; }
};

}  // namespace lipdrive
