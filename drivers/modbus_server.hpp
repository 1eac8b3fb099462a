// A Modbus slave (server) over TCP or RTU on libmodbus 3.1. Never includes core/.
//
// Thread model: the constructor tries to bind the socket or open the serial device, then one
// thread of its own owns the libmodbus context and the register mapping until destruction;
// when that first try failed (a port taken, a device not there yet), the thread tries again
// with back-off. port(), describe() and healthy() may be called from any thread.
// The owner's callbacks run on that thread: `refresh` fills the mapping before every request
// is answered, so a reply always shows the newest state; `written` reports what a request
// writes to holding registers before the acknowledgement goes out, so a master that has its
// acknowledgement knows the owner has seen the write. Out-of-range addresses and bad counts get
// Modbus exception responses from libmodbus, function codes the register map does not list
// exception 1 (illegal function) from the server; a TCP client that sends something
// unparseable, or a request too slowly (kRequestTimeoutMs), is disconnected without disturbing
// the others.
#pragma once

#include "drivers/modbus_link.hpp"
#include "drivers/unique_fd.hpp"

#include <atomic>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <thread>
#include <vector>

namespace lipdrive {

class ModbusServer {
 public:
  /// Fills the input and holding registers (their whole extent) before a request is answered.
  using Refresh = std::function<void(std::span<std::uint16_t> input, std::span<std::uint16_t> holding)>;
  /// A request writes `values` to holding registers from `address` on (the reply follows).
  using Written = std::function<void(int address, std::span<const std::uint16_t> values)>;

  /// Serves `input_registers` input and `holding_registers` holding registers at address 0.
  /// TCP: listens on endpoint.address:endpoint.port (port 0: any free port, see port()) and
  /// serves up to max_clients connections at once; a connection beyond that closes the client
  /// whose last request is oldest if that was kQuietBeforeClosingMs ago or more (one left
  /// half-open by a rebooted PLC never sends again), else it is refused.
  /// RTU: answers requests for endpoint.unit_id.
  /// A port that cannot be bound or a device that cannot be opened is logged once, the server
  /// is unhealthy, and its thread tries again with back-off (100 ms doubling up to 5 s) until it
  /// can, logging once when it does. Throws std::runtime_error only when libmodbus or the
  /// system cannot provide the context, the register mapping or an eventfd.
  ModbusServer(const ModbusEndpoint& endpoint, int max_clients, int input_registers, int holding_registers,
               Refresh refresh, Written written);
  /// Stops the thread (promptly: it never waits longer than kByteTimeout) and closes everything.
  ~ModbusServer();
  ModbusServer(const ModbusServer&) = delete;
  ModbusServer& operator=(const ModbusServer&) = delete;

  /// TCP: the port actually bound; 0 while not listening yet.
  int port() const { return port_.load(std::memory_order_relaxed); }
  /// "tcp 0.0.0.0:1502" or "rtu /dev/ttyUSB0 ...".
  std::string describe() const;
  /// False while not listening yet (TCP), after the serial line failed (unplugged adapter) and
  /// while it could not be opened yet (RTU); the server tries again by itself.
  bool healthy() const { return healthy_.load(std::memory_order_relaxed); }

  /// How long libmodbus waits for the rest of a frame: on RTU once its first byte is there;
  /// on TCP only for a request whose PDU claims more than its MBAP length (it reads a request
  /// once the length is in). Bounds how long a broken peer holds up the others and how long
  /// destruction waits.
  static constexpr int kByteTimeoutMs = 50;
  /// TCP: how long a request may take to arrive whole once part of it is in. A request is
  /// read only when it is complete, so a slow client holds up nobody else; one still short
  /// of its length after this long is disconnected.
  static constexpr int kRequestTimeoutMs = 500;
  /// TCP: how long a client must have sent no request before a newcomer to a full server may
  /// take its place.
  static constexpr int kQuietBeforeClosingMs = 2000;

 private:
  void serve_tcp();
  void serve_rtu();
  /// TCP: listens on the endpoint (listen_fd_, port_). False with errno set when it cannot.
  bool listen();
  /// Reads one request from the context's current socket and answers it. False when the
  /// peer is gone or sent something that is not a request (the connection is then dropped).
  bool answer_one();
  /// TCP: reads what is left of a request whose MBAP length is longer than the PDU libmodbus
  /// parsed (`length` bytes; a function it does not know is read to its code alone), so that
  /// the tail is not taken for the next request.
  void skip_rest_of_request(int length);
  /// Blocks until `fd` is readable or stop; the poll result for `fd`, 0 on stop.
  short wait_readable(int fd, int timeout_ms);

  ModbusEndpoint endpoint_;
  int max_clients_;
  Refresh refresh_;
  Written written_;
  struct MappingDeleter {
    void operator()(modbus_mapping_t* mapping) const { modbus_mapping_free(mapping); }
  };
  ModbusContext context_;                                      // the server thread's
  std::unique_ptr<modbus_mapping_t, MappingDeleter> mapping_;  // the server thread's
  UniqueFd listen_fd_;                                         // tcp; the server thread's once it runs
  UniqueFd wake_fd_;  // eventfd: destruction wakes the server thread out of poll()
  std::atomic<int> port_{0};
  std::vector<std::uint8_t> query_;
  std::atomic<bool> stopping_{false}, healthy_{true};
  std::thread thread_;
};

}  // namespace lipdrive
