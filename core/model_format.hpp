// The .lpm model file format: a MorphableModel as bytes and back. Pure: no file
// I/O here (firmware_app/model_files.hpp reads and writes the files).
//
// serialize_model writes version 1 for a pose-PCA model (exact floats, the layout below) and
// version 2 for a model with expression shapes (compact: zlib, 16-bit basis); both are read.
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
//
// Layout, version 2 (E = expression shapes). Header of 56 bytes:
//
//   offset  size  field
//        0     8  magic "LPDMODEL"
//        8     4  u32 format version = 2
//       12     4  u32 N
//       16     4  u32 K
//       20     4  u32 T
//       24     4  u32 P
//       28     4  u32 E
//       32     8  u64 payload length in bytes (the zlib stream after the header)
//       40     8  u64 inflated payload length in bytes
//       48     4  u32 CRC-32 of the payload (the zlib stream as stored)
//       52     4  reserved, must be 0
//       56        payload: one zlib stream (RFC 1950) that inflates to
//                   f32           total_variance
//                   f32[3N]       mean
//                   f32[K]        stddev
//                   K times:      f32 scale + i16[3N]: basis column = scale * value
//                   u32[3T]       triangles
//                   i32[68]       landmark map
//                   P times:      u16 byte length + UTF-8 bytes (pose name)
//                   f32[K*P]      pose coefficients, column-major
//                   E times:      u16 byte length + UTF-8 bytes (expression name)
//                   E times:      f32 scale + i16[3N]: expression displacement (mm) = scale * value
//
// The 16-bit columns keep each value to within half a step, scale / 2 = max |column| / 65534:
// under 0.0005 mm for a 30 mm expression displacement. The inflated length must equal the
// sizes the header gives (read before inflating, so a forged header cannot make the reader
// allocate more than the counts say, and never more than kMaxInflatedModelBytes).
#pragma once

#include "core/morphable_model.hpp"

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive {

inline constexpr std::uint32_t kModelFormatVersion = 1;  // pose-PCA models
inline constexpr std::uint32_t kExpressionModelFormatVersion = 2;
inline constexpr std::size_t kModelHeaderSize = 40;
inline constexpr std::size_t kExpressionModelHeaderSize = 56;
inline constexpr std::uint64_t kMaxInflatedModelBytes = 1ull << 30;

/// The version serialize_model writes for this model.
std::uint32_t model_format_version(const MorphableModel& model);

/// A model file that cannot be read; the message starts with the source name.
class ModelFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Encodes a model. Throws std::invalid_argument when the model's own sizes
/// disagree (e.g. basis rows != mean size) or a pose or expression name exceeds 65535 bytes.
std::vector<std::uint8_t> serialize_model(const MorphableModel& model);

/// What identifies a model's identity space (its mean, component scales and basis): zlib's
/// CRC-32 (core/checksum.hpp) over their f32 values as held in memory. A performer's identity
/// (core/calibration.hpp) is kept with it, so coefficients fitted to one model are never
/// applied to another.
std::uint32_t identity_fingerprint(const MorphableModel& model);

/// The values deserialize_model() checks after decoding (finite numbers, positive stddev,
/// triangles and landmarks within the vertices, expression names present and distinct), for a
/// model about to be written: throws ModelFormatError starting with `source`.
void validate_model_values(const MorphableModel& model, const std::string& source);

/// Decodes and validates a model; source_name (usually the file path) starts
/// every error message. Never reads outside `bytes`.
MorphableModel deserialize_model(std::span<const std::uint8_t> bytes, const std::string& source_name);

}  // namespace lipdrive
