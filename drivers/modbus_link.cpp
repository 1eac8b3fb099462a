#include "drivers/modbus_link.hpp"

#include <fmt/format.h>
#include <modbus/modbus-rtu.h>
#include <modbus/modbus-tcp.h>
#include <spdlog/spdlog.h>

#include <cerrno>
#include <stdexcept>

namespace lipdrive {

std::string describe(const ModbusEndpoint& endpoint) {
  if (endpoint.transport == ModbusEndpoint::Transport::kTcp)
    return fmt::format("tcp {}:{}", endpoint.address, endpoint.port);
  const SerialPortSettings& line = endpoint.line;
  return fmt::format("rtu {} {} {}{}{} unit {}", line.device, line.baud, line.data_bits, line.parity, line.stop_bits,
                     endpoint.unit_id);
}

void ModbusContextDeleter::operator()(modbus_t* context) const {
  modbus_close(context);
  modbus_free(context);
}

ModbusContext make_context(const ModbusEndpoint& endpoint) {
  modbus_t* raw = endpoint.transport == ModbusEndpoint::Transport::kTcp
                      ? modbus_new_tcp(endpoint.address.c_str(), endpoint.port)
                      : modbus_new_rtu(endpoint.line.device.c_str(), endpoint.line.baud, endpoint.line.parity,
                                       endpoint.line.data_bits, endpoint.line.stop_bits);
  if (raw == nullptr)
    throw std::runtime_error(fmt::format("modbus {}: {}", describe(endpoint), modbus_strerror(errno)));
  ModbusContext context(raw);
  if (modbus_set_slave(raw, endpoint.unit_id) == -1)
    throw std::runtime_error(
        fmt::format("modbus {}: unit id {}: {}", describe(endpoint), endpoint.unit_id, modbus_strerror(errno)));
  return context;
}

bool connect_context(modbus_t* context, const ModbusEndpoint& endpoint) {
  if (modbus_connect(context) == -1) return false;
  if (endpoint.transport == ModbusEndpoint::Transport::kRtu && endpoint.line.rs485 &&
      modbus_rtu_set_serial_mode(context, MODBUS_RTU_RS485) == -1)
    spdlog::warn("modbus {}: cannot switch to RS-485 mode ({}); relying on the adapter", describe(endpoint),
                 modbus_strerror(errno));
  return true;
}

namespace {

void set_timeout(modbus_t* context, std::chrono::milliseconds timeout) {
  const auto us = static_cast<std::uint32_t>(std::chrono::microseconds(timeout).count());
  modbus_set_response_timeout(context, us / 1'000'000, us % 1'000'000);
}

}  // namespace

ModbusClient::ModbusClient(const ModbusEndpoint& endpoint, std::chrono::milliseconds timeout)
    : endpoint_(endpoint), context_(make_context(endpoint)) {
  // The response timeout also bounds the TCP connect in libmodbus.
  set_timeout(context_.get(), timeout);
}

bool ModbusClient::connect() {
  if (connected_) return true;
  connected_ = connect_context(context_.get(), endpoint_);
  if (!connected_) last_error_ = fmt::format("connect: {}", modbus_strerror(errno));
  return connected_;
}

bool ModbusClient::write_registers(int address, std::span<const std::uint16_t> values) {
  if (!connect()) return false;
  if (modbus_write_registers(context_.get(), address, static_cast<int>(values.size()), values.data()) ==
      static_cast<int>(values.size()))
    return true;
  last_error_ = fmt::format("write: {}", modbus_strerror(errno));
  disconnect();
  return false;
}

void ModbusClient::disconnect() {
  if (connected_) modbus_close(context_.get());
  connected_ = false;
}

}  // namespace lipdrive
