#include "firmware_app/outputs/modbus_client_output.hpp"

#include "firmware_app/outputs/modbus_registers.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <span>
#include <stdexcept>

namespace lipdrive {
namespace {

std::string description(const ModbusClientOptions& options, std::span<const ChannelSpec> channels) {
  const auto count = static_cast<int>(pick_channels(options.channels, channels, "modbus client").size());
  return fmt::format("modbus client {} registers {}..{}", lipdrive::describe(options.link), options.first_register,
                     options.first_register + count - 1);
}

}  // namespace

ModbusClientOutput::ModbusClientOutput(const ModbusClientOptions& options, std::span<const ChannelSpec> channels)
    : SenderOutput(description(options, channels), options.rate_hz, std::chrono::milliseconds(options.max_backoff_ms)),
      options_(options),
      channel_indices_(pick_channels(options.channels, channels, "modbus client")),
      client_(options.link, std::chrono::milliseconds(options.timeout_ms)) {
  const int count = static_cast<int>(channel_indices_.size());
  if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || count > kMaxChannels || options.first_register < 0 ||
      options.first_register + count > 65536)
    throw std::invalid_argument(fmt::format("{}: {} channels do not fit in one write request", describe(), count));
  start();
}

bool ModbusClientOutput::send(const DriveFrame& frame) {
  std::array<std::uint16_t, kMaxChannels> registers{};
  for (std::size_t i = 0; i < channel_indices_.size(); ++i)
    registers[i] = to_register(frame.values[static_cast<std::size_t>(channel_indices_[i])]);
  return client_.write_registers(options_.first_register, {registers.data(), channel_indices_.size()});
}

}  // namespace lipdrive
