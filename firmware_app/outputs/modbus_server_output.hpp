// [[outputs.modbus_server]] (docs/data-flow.md): a Modbus slave that exposes the drive through one
// register map (modbus_registers.hpp, docs/modbus-register-map.md), the same for TCP and RTU.
//
// Thread model: publish() runs on the pipeline's output thread and only stores the frame in a
// seqlock. The server's own thread (drivers/modbus_server.hpp) owns the libmodbus context and,
// for every request, reads the newest frame from the seqlock and writes commands to the
// DriveControl; network or serial I/O never reaches publish().
#pragma once

#include "core/drive_channels.hpp"
#include "drivers/modbus_server.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/daemon/latest_frame.hpp"
#include "firmware_app/outputs/modbus_registers.hpp"
#include "firmware_app/outputs/output.hpp"

#include <cstdint>
#include <span>
#include <string>

namespace lipdrive {

/// Serves the register map. Control registers write `control`; the channel and status
/// registers (and the record register) show the newest published DriveFrame.
class ModbusServerOutput : public Output {
 public:
  /// Binds the port or opens the serial device at once; when that fails (a port taken, a device
  /// not there yet) the output is unhealthy and the server tries again with back-off
  /// (drivers/modbus_server.hpp). Throws std::invalid_argument for more than kMaxChannels
  /// channels, std::runtime_error when libmodbus rejects the link's settings. `control` must
  /// outlive the output.
  ModbusServerOutput(const ModbusServerOptions& options, std::span<const ChannelSpec> channels, DriveControl& control);

  void publish(const DriveFrame& frame) override { latest_.publish(frame); }
  std::string describe() const override { return "modbus server " + server_.describe(); }
  bool healthy() const override { return server_.healthy(); }

  /// TCP: the port actually bound (options.link.port 0 picks a free one).
  int port() const { return server_.port(); }

 private:
  // Both run on the server thread.
  void refresh(std::span<std::uint16_t> input, std::span<std::uint16_t> holding) const;
  void written(int address, std::span<const std::uint16_t> values);

  int channel_count_;
  DriveControl& control_;
  DriveFrame neutral_frame_;  // what the registers show until the first frame is published
  Published<DriveFrame> latest_;
  ModbusServer server_;  // last: its thread uses the members above
};

}  // namespace lipdrive
