#include "firmware_app/outputs/make_outputs.hpp"

#include "firmware_app/outputs/dmx_output.hpp"
#include "firmware_app/outputs/gpio_output.hpp"
#include "firmware_app/outputs/modbus_client_output.hpp"
#include "firmware_app/outputs/modbus_server_output.hpp"
#include "firmware_app/outputs/osc_output.hpp"
#include "firmware_app/outputs/serial_output.hpp"

#include <fmt/format.h>

namespace lipdrive {
namespace {

/// Runs `open` (opening or checking [outputs.gpio]); a GpioError, which can never work on
/// this machine, becomes the configuration's error naming the key.
template <typename Open>
auto gpio_key(const Config& config, Open&& open) {
  try {
    return open();
  } catch (const GpioError& e) {
    throw ConfigError(fmt::format("{}: key outputs.gpio: {}", config.file.string(), e.what()));
  }
}

}  // namespace

std::vector<std::unique_ptr<Output>> make_outputs(const Config& config, DriveControl& control) {
  std::vector<std::unique_ptr<Output>> outputs;
  for (const ModbusServerOptions& options : config.outputs.modbus_servers)
    outputs.push_back(std::make_unique<ModbusServerOutput>(options, config.channels, control));
  for (const ModbusClientOptions& options : config.outputs.modbus_clients)
    outputs.push_back(std::make_unique<ModbusClientOutput>(options, config.channels));
  for (const SerialOutputOptions& options : config.outputs.serial)
    outputs.push_back(std::make_unique<SerialOutput>(options, config.channels));
  for (const DmxOutputOptions& options : config.outputs.dmx) outputs.push_back(std::make_unique<DmxOutput>(options));
  for (const OscOutputOptions& options : config.outputs.osc) {
    try {
      outputs.push_back(std::make_unique<OscOutput>(options, config.channels));
    } catch (const UdpError& e) {
      // Resolved when the file was loaded; a name server that changed its mind since.
      fail_unresolved(fmt::format("{}: key outputs.osc", config.file.string()), e);
    }
  }
  if (config.outputs.gpio.enabled)
    outputs.push_back(gpio_key(config, [&] {
      return std::make_unique<GpioOutput>(config.outputs.gpio, open_gpio_chip(config.outputs.gpio), control);
    }));
  return outputs;
}

void check_outputs(const Config& config) {
  if (config.outputs.gpio.enabled) gpio_key(config, [&] { check_gpio_chip(config.outputs.gpio); });
}

}  // namespace lipdrive
