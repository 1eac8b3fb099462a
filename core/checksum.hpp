// The one checksum of lipdrive's file formats (the .lpm model, the .lpp predictor): zlib's
// CRC-32 (IEEE 802.3 polynomial, reflected 0xEDB88320, initial and final XOR 0xFFFFFFFF), the
// checksum of zlib, PNG and Ethernet.
#pragma once

#include <cstdint>
#include <span>

namespace lipdrive {

/// The CRC-32 of `bytes`; `previous`, the CRC-32 of what came before them (0: nothing), continues it.
std::uint32_t crc32(std::span<const std::uint8_t> bytes, std::uint32_t previous = 0);

}  // namespace lipdrive
