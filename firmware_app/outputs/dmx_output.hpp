// [[outputs.dmx]] (docs/dmx.md): the drive's channels as DMX512 slots of one universe, sent to
// olad (drivers/ola_client.hpp), which carries them on as sACN, Art-Net or to a USB widget.
//
// A full universe takes 22.7 ms on a DMX512 line, so DMX carries at most 44 frames a second:
// the sender thread sends the newest drive frame at most rate_hz (<= 44) times a second and
// older ones are skipped (latest wins); at 60 fps about every fourth frame is skipped. The
// drive publishes at least every output tick (20 ms), so the universe is refreshed even while
// nothing moves, as receivers expect. The last frame sent is the neutral pose. olad absent or
// restarted: the output reports itself failing and reconnects with the shared back-off.
//
// Thread model: that of every SenderOutput (sender_output.hpp); the OLA client is the sender
// thread's. An olad that hangs is noticed when its socket's buffers are full (docs/dmx.md).
#pragma once

#include "drivers/ola_client.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/outputs/sender_output.hpp"

#include <array>
#include <cstdint>
#include <string>

namespace lipdrive {

class DmxOutput : public SenderOutput {
 public:
  /// Does not connect yet (the sender thread does, and retries). The footprint was checked
  /// by the configuration (check_footprint()).
  explicit DmxOutput(const DmxOutputOptions& options);
  ~DmxOutput() override { stop(); }

 private:
  bool send(const DriveFrame& frame) override;
  std::string failure() const override { return client_.last_error(); }
  void close() override;

  DmxOutputOptions options_;
  std::size_t slots_ = 0;                                   // sent: slot 1 up to the highest one the footprint uses
  OlaDmxClient client_;                                     // the sender thread's
  std::array<std::uint8_t, kDmxUniverseSlots> universe_{};  // the sender thread's
};

}  // namespace lipdrive
