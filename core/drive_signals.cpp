#include "core/drive_signals.hpp"

namespace lipdrive {
namespace {

// The names in Signal order: the measures, "viseme_" + kVisemeNames, "arkit_" + kArkitNames,
// laid end to end in one constant array.
constexpr std::array<std::string_view, static_cast<int>(Signal::kFirstViseme)> kMeasureNames{
    "open", "width", "protrusion", "tracking", "seal"};
constexpr std::string_view kVisemePrefix = "viseme_", kArkitPrefix = "arkit_";

constexpr std::size_t kNameChars = [] {
  std::size_t chars = 0;
  for (const std::string_view name : kMeasureNames) chars += name.size();
  for (const std::string_view name : kVisemeNames) chars += kVisemePrefix.size() + name.size();
  for (const std::string_view name : kArkitNames) chars += kArkitPrefix.size() + name.size();
  return chars;
}();

struct NameTable {
  std::array<char, kNameChars> chars{};
  std::array<std::size_t, kNumSignals + 1> starts{};  // signal s: chars[starts[s], starts[s + 1])
};

constexpr NameTable make_names() {
  NameTable table;
  std::size_t at = 0, signal = 0;
  const auto add = [&](std::string_view prefix, std::string_view name) {
    table.starts[signal++] = at;
    for (const char c : prefix) table.chars[at++] = c;
    for (const char c : name) table.chars[at++] = c;
  };
  for (const std::string_view name : kMeasureNames) add("", name);
  for (const std::string_view name : kVisemeNames) add(kVisemePrefix, name);
  for (const std::string_view name : kArkitNames) add(kArkitPrefix, name);
  table.starts[signal] = at;
  return table;
}

constexpr NameTable kNames = make_names();

}  // namespace

std::string_view signal_name(Signal signal) {
  const auto s = static_cast<std::size_t>(signal);
  return {kNames.chars.data() + kNames.starts[s], kNames.starts[s + 1] - kNames.starts[s]};
}

std::optional<Signal> parse_signal(std::string_view name) {
  for (int s = 0; s < kNumSignals; ++s)
    if (signal_name(static_cast<Signal>(s)) == name) return static_cast<Signal>(s);
  return std::nullopt;
}

}  // namespace lipdrive
