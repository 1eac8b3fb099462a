// The Modbus register map (docs/modbus-register-map.md): one table for TCP and RTU, for the
// server output, and the one way a channel value becomes a register.
#pragma once

#include <cstdint>

namespace lipdrive {

/// Register addresses (0-based, as on the wire).
namespace modbus_map {
// Input registers (function 4).
inline constexpr int kStatus = 0;        // the status word (daemon/status_word.hpp)
inline constexpr int kHeartbeat = 1;     // DriveFrame::counter, low 16 bits
inline constexpr int kSequenceHigh = 2;  // DriveFrame::sequence, low 32 bits, high word first
inline constexpr int kSequenceLow = 3;
inline constexpr int kLatencyUsHigh = 4;  // capture -> processed, µs, 32 bits, high word first
inline constexpr int kLatencyUsLow = 5;
inline constexpr int kFpsTenths = 6;  // processed frames per second × 10
inline constexpr int kChannelCount = 7;
// The newest frame's timecode ([timecode]; docs/modbus-register-map.md).
inline constexpr int kTimecodeHoursMinutes = 8;   // hours · 256 + minutes
inline constexpr int kTimecodeSecondsFrames = 9;  // seconds · 256 + frames
inline constexpr int kTimecodeState = 10;         // bit 0 valid, bit 1 drop-frame
inline constexpr int kTimecodeRate = 11;          // frames per second × 100 (2400, 2500, 2997, 3000)
inline constexpr int kFirstChannel = 16;          // one register per channel, ChannelBank order
// Holding registers (functions 3, 6, 16, 22, 23).
inline constexpr int kOutputEnable = 0;    // 0 off, anything else on
inline constexpr int kCalibrate = 1;       // write 1: calibrate neutral; reads 0
inline constexpr int kRecord = 2;          // write 1 start / 0 stop; reads 1 while recording
inline constexpr int kFirstOverride = 16;  // one register per channel
inline constexpr std::uint16_t kNoOverride = 0xFFFF;
}  // namespace modbus_map

/// A value in output units as a register: rounded, clamped to 0..65535 (NaN: 0).
std::uint16_t to_register(double value);

}  // namespace lipdrive
