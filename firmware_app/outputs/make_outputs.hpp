// The drive outputs a configuration asks for (Modbus servers and clients, serial lines, DMX,
// GPIO):
// the one place that knows every kind.
#pragma once

#include "firmware_app/config/config.hpp"
#include "firmware_app/outputs/output.hpp"

#include <memory>
#include <vector>

namespace lipdrive {

/// One output per configured entry, in the order of the file. Devices that are missing or go
/// away are retried by each output on its own; only what can never work (a GPIO chip or line
/// that does not exist) throws ConfigError.
std::vector<std::unique_ptr<Output>> make_outputs(const Config& config, DriveControl& control);

/// For `lipdrive check-config`: what make_outputs() would refuse, found without claiming
/// anything (the GPIO chip and lines looked up, not requested). Throws ConfigError.
void check_outputs(const Config& config);

}  // namespace lipdrive
