#include "core/dmx_footprint.hpp"

#include <algorithm>
#include <array>
#include <cmath>

namespace lipdrive {

std::optional<DmxFootprintError> check_footprint(std::span<const DmxSlotSpec> footprint) {
  constexpr std::size_t kFree = static_cast<std::size_t>(-1);
  std::array<std::size_t, kDmxUniverseSlots + 1> owner;  // by address; index 0 unused
  owner.fill(kFree);
  for (std::size_t i = 0; i < footprint.size(); ++i) {
    const DmxSlotSpec& spec = footprint[i];
    if (spec.address < 1 || spec.last_address() > kDmxUniverseSlots) {
      return DmxFootprintError{i, spec.sixteen_bit
                                      ? "a 16-bit channel needs two slots: address must be between 1 and 511, got " +
                                            std::to_string(spec.address)
                                      : "address must be between 1 and 512, got " + std::to_string(spec.address)};
    }
    if (!(spec.range_min != spec.range_max))
      return DmxFootprintError{i, "channel \"" + spec.channel + "\" has an empty output range"};
    for (int address = spec.address; address <= spec.last_address(); ++address) {
      const std::size_t other = owner[static_cast<std::size_t>(address)];
      if (other != kFree) {
        const DmxSlotSpec& first = footprint[other];
        return DmxFootprintError{i, "channel \"" + spec.channel + "\" at address " + std::to_string(spec.address) +
                                        " collides with channel \"" + first.channel + "\" (addresses " +
                                        std::to_string(first.address) + ".." + std::to_string(first.last_address()) +
                                        ") at address " + std::to_string(address)};
      }
      owner[static_cast<std::size_t>(address)] = i;
    }
  }
  return std::nullopt;
}

std::uint16_t dmx_level(const DmxSlotSpec& spec, double value) {
  if (std::isnan(value)) return 0;
  const double position = std::clamp((value - spec.range_min) / (spec.range_max - spec.range_min), 0.0, 1.0);
  const double full = spec.sixteen_bit ? 65535.0 : 255.0;
  return static_cast<std::uint16_t>(std::lround(position * full));
}

void encode_dmx(std::span<const DmxSlotSpec> footprint, std::span<const double> values,
                std::span<std::uint8_t, kDmxUniverseSlots> universe) {
  for (const DmxSlotSpec& spec : footprint) {
    const std::uint16_t level = dmx_level(spec, values[static_cast<std::size_t>(spec.channel_index)]);
    const auto slot = static_cast<std::size_t>(spec.address - 1);
    if (spec.sixteen_bit) {
      universe[slot] = static_cast<std::uint8_t>(level >> 8);
      universe[slot + 1] = static_cast<std::uint8_t>(level & 0xFF);
    } else {
      universe[slot] = static_cast<std::uint8_t>(level);
    }
  }
}

}  // namespace lipdrive
