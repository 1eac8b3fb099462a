// The bytes the serial outputs put on the wire (docs/serial-protocol.md, docs/maestro.md).
// Pure functions on plain arrays: no I/O, no allocation, no knowledge of channels or frames
// beyond numbers, so a microcontroller-side implementation can be checked against them.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace lipdrive::serial_protocol {

/// CRC-16/MODBUS: polynomial 0x8005 reflected (0xA001), initial value 0xFFFF, no final XOR.
/// The check value of the ASCII bytes "123456789" is 0x4B37. Sent low byte first.
std::uint16_t crc16_modbus(std::span<const std::uint8_t> bytes);

// ---- Framed binary --------------------------------------------------------------------
// A5 | L | seq u16 | time_us u32 | status u16 | n x value i16 | CRC u16   (all little-endian)
// L counts the bytes between itself and the CRC: 8 + 2n. The CRC covers every byte before it.

inline constexpr std::uint8_t kFrameStart = 0xA5;
inline constexpr std::size_t kFrameFixedBytes = 8;  // seq + time + status, counted in L
inline constexpr std::size_t kMaxFrameChannels = 32;

constexpr std::size_t framed_size(std::size_t channel_count) { return 2 + kFrameFixedBytes + 2 * channel_count + 2; }

struct FrameHeader {
  std::uint16_t sequence = 0;  // drive frame counter, +1 per tick; a gap = frames dropped or lost
  std::uint32_t time_us = 0;   // sender's monotonic clock in µs, wrapping every 71.6 minutes
  std::uint16_t status = 0;    // DriveFrame status bits
};

/// A value in output units as it travels: rounded to the nearest integer (halves away from
/// zero) and saturated to [-32768, 32767].
std::int16_t frame_value(double value);

/// Writes one frame to the front of `out` and returns its size, framed_size(values.size()).
/// Throws std::invalid_argument for more than kMaxFrameChannels values or too small an `out`.
std::size_t encode_framed(const FrameHeader& header, std::span<const double> values, std::span<std::uint8_t> out);

// ---- Line mode ------------------------------------------------------------------------
// "open=0.53 width=0.21\n": name=value pairs separated by one space, ended by LF.

/// Values beyond this magnitude are clamped to it, so every value fits kMaxLineValueChars.
inline constexpr double kMaxLineValue = 999'999'999.999;
inline constexpr std::size_t kMaxLineValueChars = 14;  // "-999999999.999"

/// A value with at most 3 decimals and no trailing zeros: 500, 0.5, 0.53, -12.125; a value
/// that rounds to zero is "0", never "-0". Writes to the front of `out`, returns the length.
std::size_t format_line_value(double value, std::span<char, kMaxLineValueChars> out);

/// The most bytes encode_line can need for these names.
std::size_t line_size_bound(std::span<const std::string> names);

/// Writes one line to the front of `out` and returns its length. Names and values pair by
/// index. Throws std::invalid_argument when the sizes differ or `out` is smaller than
/// line_size_bound(names).
std::size_t encode_line(std::span<const std::string> names, std::span<const double> values,
                        std::span<std::uint8_t> out);

// ---- Pololu Maestro compact protocol ---------------------------------------------------
// Set Target: 0x84, servo, target & 0x7F, (target >> 7) & 0x7F; target in quarter-µs.

inline constexpr std::uint8_t kMaestroSetTarget = 0x84;
inline constexpr std::size_t kMaestroCommandBytes = 4;
inline constexpr std::uint16_t kMaestroMaxTarget = 0x3FFF;  // 14 bits: 4095.75 µs
inline constexpr int kMaestroMaxServo = 127;                // 7 bits on the wire; Mini Maestros have up to 24

/// Pulse width in µs -> quarter-µs target, rounded to nearest, clamped to 0..kMaestroMaxTarget.
/// Note that target 0 tells the Maestro to stop sending pulses on that servo.
std::uint16_t maestro_target(double microseconds);

/// One Set Target command per servo, in order; returns the bytes written
/// (kMaestroCommandBytes * servos.size()). Throws std::invalid_argument when the sizes
/// differ, a servo number exceeds kMaestroMaxServo or `out` is too small.
std::size_t encode_maestro(std::span<const int> servos, std::span<const double> microseconds,
                           std::span<std::uint8_t> out);

}  // namespace lipdrive::serial_protocol
