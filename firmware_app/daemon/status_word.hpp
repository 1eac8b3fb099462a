// The status word: sixteen bits that tell every output (the Modbus status register, the
// serial frame header, the GPIO lines) the state of the drive. It is assembled in one place,
// status_word(), once per drive frame on the output thread, and travels in
// DriveFrame::status; outputs only read it.
#pragma once

#include "core/drive_source.hpp"

#include <cstdint>

namespace lipdrive {

/// Bits of the status word (docs/modbus-register-map.md, docs/serial-protocol.md).
enum StatusBit : std::uint16_t {
  kStatusTracking = 1 << 0,         // the newest frame has a tracked face
  kStatusCalibrated = 1 << 1,       // a performer profile is in use
  kStatusFailSafe = 1 << 2,         // channels are held at or easing to neutral
  kStatusSideCamera = 1 << 3,       // a side camera delivers and protrusion comes from it
  kStatusRecording = 1 << 4,        // a take is being recorded
  kStatusOutputsEnabled = 1 << 5,   // output enable is on and the enable switch (if any) closed
  kStatusCameraConnected = 1 << 6,  // the front camera delivers frames
  kStatusModelMismatch = 1 << 7,    // performer and model differ by two mouth-height classes
};

/// Bits 8-9 of the status word: the source that drives (DriveSource: 0 video, 1 voice,
/// 2 fail-safe).
inline constexpr int kStatusSourceShift = 8;
inline constexpr std::uint16_t kStatusSourceMask = 3 << kStatusSourceShift;

/// What the status word reports, one flag per bit.
struct DriveState {
  bool tracking = false;
  bool calibrated = false;
  bool fail_safe = true;
  bool side_camera = false;
  bool recording = false;
  bool outputs_enabled = false;
  bool camera_connected = false;
  bool model_mismatch = false;
  DriveSource source = DriveSource::kFailSafe;
};

std::uint16_t status_word(const DriveState& state);
/// The source a status word reports.
DriveSource status_source(std::uint16_t status);

}  // namespace lipdrive
