// The .lpm model file format: a MorphableModel as bytes and back. Pure: no file
// I/O here (firmware_app/model_files.hpp reads and writes the files).
//
// Layout, version 1. All integers and floats are little-endian; floats are
// IEEE-754 binary32. N = vertices, K = components, T = triangles, P = poses.
//
//   offset  size  field
//        0     8  magic "LPDMODEL" (ASCII, no terminator)
//        8     4  u32 format version = 1
//       12     4  u32 N
//       16     4  u32 K
//       20     4  u32 T
//       24     4  u32 P
//       28     8  u64 payload length in bytes (the bytes after the header)
//       36     4  u32 CRC-32 of the payload (zlib's crc32: the IEEE 802.3 polynomial)
//       40        payload:
//                   f32           total_variance
//                   f32[3N]       mean (x1,y1,z1,...,xN,yN,zN)
//                   f32[K]        stddev
//                   f32[3N*K]     basis, column-major (component 0's 3N values first)
//                   u32[3T]       triangles (vertex indices, 0-based)
//                   i32[68]       landmark map: iBUG index -> vertex, -1 = unmapped
//                   P times:      u16 byte length + that many UTF-8 bytes (pose name)
//                   f32[K*P]      pose coefficients, column-major (pose 0's K values first)
//
// The file ends exactly at the end of the payload.
#pragma once

#include "core/morphable_model.hpp"

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive {

inline constexpr std::uint32_t kModelFormatVersion = 1;
inline constexpr std::size_t kModelHeaderSize = 40;

/// A model file that cannot be read; the message starts with the source name.
class ModelFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Encodes a model. Throws std::invalid_argument when the model's own sizes
/// disagree (e.g. basis rows != mean size) or a pose name exceeds 65535 bytes.
std::vector<std::uint8_t> serialize_model(const MorphableModel& model);

/// Decodes and validates a model; source_name (usually the file path) starts
/// every error message. Never reads outside `bytes`.
MorphableModel deserialize_model(std::span<const std::uint8_t> bytes, const std::string& source_name);

}  // namespace lipdrive
