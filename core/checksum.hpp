// The one checksum of lipdrive's file formats (the .lpm model, the .lpp predictor): zlib's
// CRC-32 (IEEE 802.3 polynomial, reflected 0xEDB88320, initial and final XOR 0xFFFFFFFF), the
// checksum of zlib, PNG and Ethernet.
#pragma once

#include <cstdint>
#include <span>

namespace lipdrive {

std::uint32_t crc32(std::span<const std::uint8_t> bytes);

}  // namespace lipdrive
