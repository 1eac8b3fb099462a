#include "drivers/serial_protocol.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace lipdrive::serial_protocol {
namespace {

void require(bool condition, const char* message) {
  if (!condition) throw std::invalid_argument(message);
}

std::uint8_t* put_le16(std::uint8_t* at, std::uint16_t value) {
  at[0] = static_cast<std::uint8_t>(value);
  at[1] = static_cast<std::uint8_t>(value >> 8);
  return at + 2;
}

std::uint8_t* put_le32(std::uint8_t* at, std::uint32_t value) {
  return put_le16(put_le16(at, static_cast<std::uint16_t>(value)), static_cast<std::uint16_t>(value >> 16));
}

}  // namespace

std::uint16_t crc16_modbus(std::span<const std::uint8_t> bytes) {
  // Bitwise rather than a 512-byte table: frames are under 80 bytes, and this is the form a
  // microcontroller sketch copies.
  std::uint16_t crc = 0xFFFF;
  for (std::uint8_t byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) crc = (crc & 1) ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001) : (crc >> 1);
  }
  return crc;
}

std::int16_t frame_value(double value) {
  return static_cast<std::int16_t>(std::lround(std::clamp(value, -32768.0, 32767.0)));
}

std::size_t encode_framed(const FrameHeader& header, std::span<const double> values, std::span<std::uint8_t> out) {
  require(values.size() <= kMaxFrameChannels, "framed serial protocol: more than 32 channels");
  const std::size_t size = framed_size(values.size());
  require(out.size() >= size, "framed serial protocol: output buffer too small");
  std::uint8_t* at = out.data();
  *at++ = kFrameStart;
  *at++ = static_cast<std::uint8_t>(kFrameFixedBytes + 2 * values.size());
  at = put_le16(at, header.sequence);
  at = put_le32(at, header.time_us);
  at = put_le16(at, header.status);
  for (double value : values) at = put_le16(at, static_cast<std::uint16_t>(frame_value(value)));
  put_le16(at, crc16_modbus(out.first(size - 2)));
  return size;
}

std::size_t format_line_value(double value, std::span<char, kMaxLineValueChars> out) {
  // Rounding to 3 decimals first decides the sign: -0.0004 prints as "0", not "-0".
  double rounded = std::round(std::clamp(value, -kMaxLineValue, kMaxLineValue) * 1000.0) / 1000.0;
  if (rounded == 0) rounded = 0;  // turns -0.0 into +0.0
  char text[32];
  int length = std::snprintf(text, sizeof text, "%.3f", rounded);
  // "%.3f" always prints a '.' for finite values; strip the zeros that carry no information.
  if (std::memchr(text, '.', static_cast<std::size_t>(length)) != nullptr) {
    while (text[length - 1] == '0') --length;
    if (text[length - 1] == '.') --length;
  }
  const auto size = std::min(static_cast<std::size_t>(length), out.size());
  std::memcpy(out.data(), text, size);
  return size;
}

std::size_t line_size_bound(std::span<const std::string> names) {
  std::size_t bound = 0;
  for (const auto& name : names) bound += name.size() + 1 + kMaxLineValueChars + 1;  // name=value then ' ' or '\n'
  return std::max<std::size_t>(bound, 1);                                            // an empty line is still its '\n'
}

std::size_t encode_line(std::span<const std::string> names, std::span<const double> values,
                        std::span<std::uint8_t> out) {
  require(names.size() == values.size(), "line serial protocol: names and values differ in number");
  require(out.size() >= line_size_bound(names), "line serial protocol: output buffer too small");
  std::size_t at = 0;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out[at++] = ' ';
    std::memcpy(out.data() + at, names[i].data(), names[i].size());
    at += names[i].size();
    out[at++] = '=';
    at += format_line_value(
        values[i], std::span<char, kMaxLineValueChars>(reinterpret_cast<char*>(out.data() + at), kMaxLineValueChars));
  }
  out[at++] = '\n';
  return at;
}

std::uint16_t maestro_target(double microseconds) {
  return static_cast<std::uint16_t>(std::lround(std::clamp(microseconds * 4.0, 0.0, double{kMaestroMaxTarget})));
}

std::size_t encode_maestro(std::span<const int> servos, std::span<const double> microseconds,
                           std::span<std::uint8_t> out) {
  require(servos.size() == microseconds.size(), "maestro protocol: servos and values differ in number");
  require(out.size() >= kMaestroCommandBytes * servos.size(), "maestro protocol: output buffer too small");
  std::size_t at = 0;
  for (std::size_t i = 0; i < servos.size(); ++i) {
    require(servos[i] >= 0 && servos[i] <= kMaestroMaxServo, "maestro protocol: servo number outside 0..127");
    const std::uint16_t target = maestro_target(microseconds[i]);
    out[at++] = kMaestroSetTarget;
    out[at++] = static_cast<std::uint8_t>(servos[i]);
    out[at++] = static_cast<std::uint8_t>(target & 0x7F);
    out[at++] = static_cast<std::uint8_t>((target >> 7) & 0x7F);
  }
  return at;
}

}  // namespace lipdrive::serial_protocol
