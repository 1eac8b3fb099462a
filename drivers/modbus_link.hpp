// Thin RAII over libmodbus 3.1 (docs/data-flow.md): where a Modbus peer is (TCP or RTU), an owned
// context, and a client that writes holding registers. Never includes core/.
//
// Thread model: a libmodbus context is not thread-safe. Every object here is used by one
// thread at a time; the owner hands it to its worker thread before starting it.
#pragma once

#include "drivers/serial_port.hpp"

#include <modbus/modbus.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

namespace lipdrive {

/// Modbus/TCP's registered port is 502, which needs privileges; lipdrive serves 1502.
inline constexpr int kDefaultModbusTcpPort = 1502;

/// A Modbus peer: TCP address and port, or RTU over a serial line.
struct ModbusEndpoint {
  enum class Transport { kTcp, kRtu };
  Transport transport = Transport::kTcp;
  std::string address = "127.0.0.1";  // tcp
  int port = kDefaultModbusTcpPort;   // tcp
  SerialPortSettings line;            // rtu; rs485: let the kernel driver switch the transceiver
  int unit_id = 1;                    // slave id, 1..247
};

/// "tcp 127.0.0.1:1502" or "rtu /dev/ttyUSB0 115200 8N1 unit 1".
std::string describe(const ModbusEndpoint& endpoint);

struct ModbusContextDeleter {
  void operator()(modbus_t* context) const;
};
using ModbusContext = std::unique_ptr<modbus_t, ModbusContextDeleter>;

/// A context for `endpoint` with its unit id set, not yet connected. Throws
/// std::runtime_error when libmodbus rejects the settings.
ModbusContext make_context(const ModbusEndpoint& endpoint);

/// Opens the connection (TCP connect, or the serial device) and, for RTU with rs485, switches
/// the line to RS-485 mode; a driver that cannot do that is logged, not fatal (many USB
/// adapters switch the transceiver by themselves). Returns false and leaves errno set when the
/// connection cannot be opened.
bool connect_context(modbus_t* context, const ModbusEndpoint& endpoint);

/// A Modbus master that writes blocks of holding registers. Connects lazily; any failure
/// closes the connection so that a late answer to a timed-out request can never be taken
/// for the answer to the next one.
class ModbusClient {
 public:
  /// `timeout` bounds every connect and every request.
  ModbusClient(const ModbusEndpoint& endpoint, std::chrono::milliseconds timeout);

  /// True when connected afterwards; on failure last_error() says why.
  bool connect();
  /// Function 16 (write multiple registers). False on any failure, which also disconnects.
  bool write_registers(int address, std::span<const std::uint16_t> values);
  void disconnect();
  bool connected() const { return connected_; }
  const std::string& last_error() const { return last_error_; }

 private:
  ModbusEndpoint endpoint_;
  ModbusContext context_;
  bool connected_ = false;
  std::string last_error_;
};

}  // namespace lipdrive
