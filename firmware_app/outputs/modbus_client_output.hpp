// [[outputs.modbus_client]] (docs/data-flow.md): writes chosen channels to holding registers of a
// remote Modbus slave (a PLC, a servo drive).
//
// Thread model: that of every SenderOutput (sender_output.hpp): the output's own thread owns
// the libmodbus context and writes the newest frame; a slow or absent slave never reaches
// publish().
#pragma once

#include "core/drive_channels.hpp"
#include "drivers/modbus_link.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/outputs/sender_output.hpp"

#include <span>
#include <string>
#include <vector>

namespace lipdrive {

/// Writes the channels (uint16, output units, modbus_registers.hpp's to_register) to
/// consecutive holding registers, at most rate_hz times a second and only when a newer frame
/// exists. A failed request drops the connection; reconnection backs off exponentially
/// (core/backoff.hpp) up to max_backoff_ms.
class ModbusClientOutput : public SenderOutput {
 public:
  /// Throws std::invalid_argument naming an unknown channel, or when the channels do not fit
  /// in one write request (123 registers) or the 16-bit address space.
  ModbusClientOutput(const ModbusClientOptions& options, std::span<const ChannelSpec> channels);
  /// Writes the newest frame if it has not gone out yet (the pipeline's last one is the
  /// neutral pose), then stops; waits at most about two timeouts.
  ~ModbusClientOutput() override { stop(); }

 private:
  bool send(const DriveFrame& frame) override;
  std::string failure() const override { return client_.last_error(); }
  void close() override { client_.disconnect(); }
  bool send_waits_for_peer() const override { return true; }

  ModbusClientOptions options_;
  std::vector<int> channel_indices_;  // DriveFrame::values index per register
  ModbusClient client_;               // the sender thread's
};

}  // namespace lipdrive
