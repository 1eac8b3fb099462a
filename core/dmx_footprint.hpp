// The DMX512 footprint of a drive (docs/dmx.md): which slots of a universe each channel
// occupies and the slot values for a channel value. A channel is 8-bit (one slot) or
// 16-bit, coarse then fine in two consecutive slots, the convention of DMX servo decoders
// and moving-light pan/tilt. The channel's output range [out_min, out_max] spans the whole
// DMX range (0..255 or 0..65535). Pure computation, no allocation in encode_dmx().
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>

namespace lipdrive {

/// Slots in a universe; addresses are 1-based, as on a console.
inline constexpr int kDmxUniverseSlots = 512;

struct DmxSlotSpec {
  std::string channel;                  // the drive channel's name (messages, footprint table)
  int channel_index = 0;                // its index in the drive's values
  int address = 1;                      // first slot, 1..512
  bool sixteen_bit = false;             // coarse at address, fine at address + 1
  double range_min = 0, range_max = 1;  // the channel's out_min, out_max: DMX 0 and full
  int last_address() const { return address + (sixteen_bit ? 1 : 0); }
};

/// What makes a footprint unsendable: the entry at `index` and why.
struct DmxFootprintError {
  std::size_t index = 0;
  std::string reason;
};

/// An address outside 1..512 (a 16-bit channel needs address + 1 as well), an empty range,
/// or a slot claimed by two channels; nullopt when every entry fits.
std::optional<DmxFootprintError> check_footprint(std::span<const DmxSlotSpec> footprint);

/// The DMX level of a value in the channel's output units: the position in
/// [range_min, range_max], clamped, times 255 (8-bit) or 65535 (16-bit), rounded.
/// NaN gives 0.
std::uint16_t dmx_level(const DmxSlotSpec& spec, double value);

/// Writes the slots of every entry into `universe` (slot 1 at index 0); other slots are
/// left as they are. `values` are the drive's channel values, indexed by channel_index.
void encode_dmx(std::span<const DmxSlotSpec> footprint, std::span<const double> values,
                std::span<std::uint8_t, kDmxUniverseSlots> universe);

}  // namespace lipdrive
