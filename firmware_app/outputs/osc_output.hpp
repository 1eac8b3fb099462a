// [[outputs.osc]] (docs/osc.md): every drive frame as one OSC bundle over UDP (liblo), time-
// tagged with the frame's capture time: the configured channels under /lipdrive/<channel>,
// FaceOSC's mouth gestures, ARKit blendshape weights under Apple's names.
//
// The capture time is CLOCK_MONOTONIC; the time tag is that moment on the wall clock
// (drivers/clock.hpp wall_time_ns(): plus the offset between CLOCK_REALTIME and
// CLOCK_MONOTONIC at sending), in NTP format.
//
// Thread model: that of every SenderOutput (sender_output.hpp). The two bundle layouts (with
// and without the timecode) are built once, here; the sender thread writes each frame's values
// into one of them and sends it, allocating nothing.
#pragma once

#include "drivers/osc_sender.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/outputs/sender_output.hpp"

#include <span>
#include <string>
#include <vector>

namespace lipdrive {

class OscOutput : public SenderOutput {
 public:
  /// Resolves the host (UdpError when it does not resolve); throws std::invalid_argument
  /// naming an unknown channel.
  OscOutput(const OscOutputOptions& options, std::span<const ChannelSpec> channels);
  ~OscOutput() override { stop(); }

 private:
  bool send(const DriveFrame& frame) override;
  std::string failure() const override { return failure_; }

  /// Writes the frame into `bundle` (laid out by bundle_layout with or without the timecode).
  void fill(OscBundle& bundle, const DriveFrame& frame, bool with_timecode) const;

  std::vector<int> channel_indices_;
  OscBundle with_timecode_, without_timecode_;  // the sender thread's
  OscSender sender_;                            // the sender thread's
  std::string failure_;                         // the sender thread's
};

}  // namespace lipdrive
