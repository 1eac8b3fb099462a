#include "firmware_app/outputs/modbus_registers.hpp"

#include <algorithm>
#include <cmath>

namespace lipdrive {

std::uint16_t to_register(double value) {
  if (std::isnan(value)) return 0;
  return static_cast<std::uint16_t>(std::clamp(std::round(value), 0.0, 65535.0));
}

}  // namespace lipdrive
