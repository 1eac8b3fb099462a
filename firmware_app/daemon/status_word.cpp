#include "firmware_app/daemon/status_word.hpp"

namespace lipdrive {

std::uint16_t status_word(const DriveState& state) {
  std::uint16_t word = 0;
  const auto set = [&word](bool on, StatusBit bit) {
    if (on) word |= bit;
  };
  set(state.tracking, kStatusTracking);
  set(state.calibrated, kStatusCalibrated);
  set(state.fail_safe, kStatusFailSafe);
  set(state.side_camera, kStatusSideCamera);
  set(state.recording, kStatusRecording);
  set(state.outputs_enabled, kStatusOutputsEnabled);
  set(state.camera_connected, kStatusCameraConnected);
  set(state.model_mismatch, kStatusModelMismatch);
  word |= static_cast<std::uint16_t>(static_cast<unsigned>(state.source) << kStatusSourceShift);
  return word;
}

DriveSource status_source(std::uint16_t status) {
  const unsigned source = (status & kStatusSourceMask) >> kStatusSourceShift;
  return source <= static_cast<unsigned>(DriveSource::kFailSafe) ? static_cast<DriveSource>(source)
                                                                 : DriveSource::kFailSafe;
}

}  // namespace lipdrive
