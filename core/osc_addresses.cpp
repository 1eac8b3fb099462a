#include "core/osc_addresses.hpp"

#include <algorithm>

namespace lipdrive::osc {

bool is_address_part(std::string_view name) {
  constexpr std::string_view kReserved = " #*,/?[]{}";
  return !name.empty() && std::ranges::all_of(name, [&](char c) {
    return c > ' ' && c < 127 && kReserved.find(c) == std::string_view::npos;
  });
}

std::string channel_address(std::string_view channel) {
  std::string address(kChannelPrefix);
  address += channel;
  return address;
}

std::string arkit_address(std::string_view arkit_name) {
  std::string address("/");
  address += arkit_name;
  return address;
}

FaceOscGestures face_osc_gestures(const DriveSignals& signals) {
  const float open = std::clamp(signals[Signal::kOpen], 0.0f, 1.0f);
  const float width = std::clamp(signals[Signal::kWidth], 0.0f, 1.0f);
  return {.mouth_width = 10 + 8 * width, .mouth_height = 7 * open, .jaw = 20 + 5 * open};
}

}  // namespace lipdrive::osc
