#include "core/checksum.hpp"

#include <zlib.h>

namespace lipdrive {

std::uint32_t crc32(std::span<const std::uint8_t> bytes, std::uint32_t previous) {
  return static_cast<std::uint32_t>(::crc32_z(previous, bytes.data(), bytes.size()));
}

}  // namespace lipdrive
