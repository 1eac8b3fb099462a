#include "core/drive_signals.hpp"

namespace lipdrive {
namespace {

// In Signal order; the viseme names are kVisemeNames with a prefix (checked in the tests).
constexpr std::array<std::string_view, kNumSignals> kSignalNames{
    "open",         "width",          "protrusion",   "tracking",     "seal",      "viseme_Aah", "viseme_BigAah",
    "viseme_B-M-P", "viseme_Ch-J-Sh", "viseme_D-S-T", "viseme_Eee",   "viseme_Eh", "viseme_F-V", "viseme_i",
    "viseme_K",     "viseme_N",       "viseme_Oh",    "viseme_Ooh-Q", "viseme_R",  "viseme_Th",  "viseme_W"};

}  // namespace

std::string_view signal_name(Signal signal) { return kSignalNames[static_cast<int>(signal)]; }

std::optional<Signal> parse_signal(std::string_view name) {
  for (int s = 0; s < kNumSignals; ++s)
    if (kSignalNames[s] == name) return static_cast<Signal>(s);
  return std::nullopt;
}

}  // namespace lipdrive
