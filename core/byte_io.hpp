// Little-endian bytes in and out, and the header and payload checks: the common parts of
// lipdrive's binary files (the .lpm morphable model, the .lpv voice model). Pure, header-only;
// the checksum is core/checksum.hpp's.
#pragma once

#include "core/checksum.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

/// `size` bytes at `offset`, little-endian; the caller checks the extent.
inline std::uint64_t get_le(std::span<const std::uint8_t> bytes, std::size_t offset, int size) {
  std::uint64_t v = 0;
  for (int i = 0; i < size; ++i) v |= std::uint64_t{bytes[offset + static_cast<std::size_t>(i)]} << (8 * i);
  return v;
}

class ByteWriter {
 public:
  void u16(std::uint16_t v) { put_le(v, 2); }
  void u32(std::uint32_t v) { put_le(v, 4); }
  void u64(std::uint64_t v) { put_le(v, 8); }
  void i32(std::int32_t v) { u32(static_cast<std::uint32_t>(v)); }
  void f32(float v) { u32(std::bit_cast<std::uint32_t>(v)); }
  void floats(const float* data, std::int64_t count) {
    for (std::int64_t i = 0; i < count; ++i) f32(data[i]);
  }
  void bytes(std::string_view s) { out_.insert(out_.end(), s.begin(), s.end()); }
  void bytes(std::span<const std::uint8_t> s) { out_.insert(out_.end(), s.begin(), s.end()); }
  /// Each as a u16 byte length and its bytes (the caller keeps names under 65536 bytes).
  void names(const std::vector<std::string>& names) {
    for (const auto& name : names) {
      u16(static_cast<std::uint16_t>(name.size()));
      bytes(name);
    }
  }
  /// A column as f32 scale + i16 values: value = scale * q, |error| <= scale / 2.
  void quantized(const float* column, std::int64_t count) {
    float largest = 0;
    for (std::int64_t i = 0; i < count; ++i) largest = std::max(largest, std::abs(column[i]));
    const float scale = largest > 0 ? largest / 32767.0f : 1.0f;
    f32(scale);
    for (std::int64_t i = 0; i < count; ++i)
      u16(static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(column[i] / scale))));
  }
  std::vector<std::uint8_t>& buffer() { return out_; }

 private:
  void put_le(std::uint64_t v, int size) {
    for (int i = 0; i < size; ++i) out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t> out_;
};

/// Sequential reader over a payload. Callers check sizes against the payload first; take()
/// still bounds-checks, so a logic slip cannot read out of bounds: it throws Error (a
/// std::runtime_error taking a message) naming the source.
template <class Error>
class ByteReader {
 public:
  ByteReader(std::span<const std::uint8_t> bytes, const std::string& source) : bytes_(bytes), source_(source) {}

  std::uint16_t u16() { return static_cast<std::uint16_t>(get_le(take(2), 0, 2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(get_le(take(4), 0, 4)); }
  std::int32_t i32() { return static_cast<std::int32_t>(u32()); }
  float f32() { return std::bit_cast<float>(u32()); }
  void floats(float* out, std::uint64_t count) {
    for (std::uint64_t i = 0; i < count; ++i) out[i] = f32();
  }
  std::string string(std::size_t length) {
    const auto s = take(length);
    return std::string(s.begin(), s.end());
  }
  /// The inverse of ByteWriter::names.
  std::vector<std::string> names(std::uint32_t count) {
    std::vector<std::string> out;
    out.reserve(count);
    for (std::uint32_t i = 0; i < count; ++i) out.push_back(string(u16()));
    return out;
  }
  /// The inverse of ByteWriter::quantized; `field` names the column in the error.
  void quantized(float* column, std::int64_t count, const char* field) {
    const float scale = f32();
    if (!std::isfinite(scale) || !(scale > 0))
      throw Error(source_ + ": " + field + " has a scale that is not a positive number");
    for (std::int64_t i = 0; i < count; ++i) column[i] = scale * static_cast<std::int16_t>(u16());
  }
  std::size_t remaining() const { return bytes_.size() - position_; }

 private:
  std::span<const std::uint8_t> take(std::size_t n) {
    if (n > remaining())
      throw Error(source_ + ": payload ends early at byte " + std::to_string(position_) +
                  " (sizes inconsistent with the payload length)");
    const auto s = bytes_.subspan(position_, n);
    position_ += n;
    return s;
  }
  std::span<const std::uint8_t> bytes_;
  std::size_t position_ = 0;
  const std::string& source_;
};

/// The start of a file: `magic`, then at least `header_size` bytes in all; else Error naming
/// the source and, for a wrong magic, what the file should have been (`kind`).
template <class Error>
void check_magic(std::span<const std::uint8_t> bytes, const std::string& source, std::string_view magic,
                 std::string_view kind, std::size_t header_size) {
  const std::size_t magic_bytes = std::min(bytes.size(), magic.size());
  if (!std::equal(magic.begin(), magic.begin() + static_cast<std::ptrdiff_t>(magic_bytes), bytes.begin()))
    throw Error(source + ": not a " + std::string(kind) + " (bad magic, expected \"" + std::string(magic) + "\")");
  if (bytes.size() < header_size)
    throw Error(source + ": truncated (expected at least " + std::to_string(header_size) + " header bytes, got " +
                std::to_string(bytes.size()) + ")");
}

/// The payload after a header of `header_size` bytes: exactly `payload_length` bytes whose
/// CRC-32 is `checksum`; else Error naming the source.
template <class Error>
std::span<const std::uint8_t> checked_payload(std::span<const std::uint8_t> bytes, const std::string& source,
                                              std::size_t header_size, std::uint64_t payload_length,
                                              std::uint32_t checksum) {
  const std::uint64_t available = bytes.size() - header_size;
  if (payload_length > available)
    throw Error(source + ": truncated (expected " + std::to_string(payload_length) +
                " payload bytes after the header, got " + std::to_string(available) + ")");
  if (payload_length < available)
    throw Error(source + ": " + std::to_string(available - payload_length) + " unexpected bytes after the payload");
  const std::span<const std::uint8_t> payload = bytes.subspan(header_size);
  const std::uint32_t actual = crc32(payload);
  if (actual != checksum)
    throw Error(source + ": checksum mismatch (header says " + std::to_string(checksum) + ", payload has " +
                std::to_string(actual) + "): the file is corrupted");
  return payload;
}

}  // namespace lipdrive
