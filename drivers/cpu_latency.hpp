// A CPU wake-up latency request: a thin wrapper over the kernel's PM QoS interface
// (/dev/cpu_dma_latency, Documentation/power/pm_qos_interface.rst).
//
// While the request is held, no CPU enters an idle state whose exit takes longer than the
// requested microseconds; the kernel drops the request when its file is closed. With 0 an idle
// core only polls, so a frame that arrives finds its core awake instead of in a deep sleep state
// that costs its wake-up and, on many processors, its caches. That costs power: an idle core
// keeps running. The daemon holds one request ([scheduling] cpu_latency_us) while the frame path
// runs.
#pragma once

#include "drivers/unique_fd.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace lipdrive {

class CpuLatencyRequest {
 public:
  static constexpr const char* kDevice = "/dev/cpu_dma_latency";

  /// Requests a wake-up latency of at most `microseconds` (>= 0) until release() or
  /// destruction; `device` is the PM QoS file (a test passes its own). Returns "" when held,
  /// otherwise why not (the file and the reason); the system's latency then stays as it is.
  std::string request(int microseconds, const std::filesystem::path& device = kDevice);

  /// The latency the CPUs keep now (the strictest request any process holds, in
  /// microseconds), or nothing when `device` cannot be read.
  static std::optional<std::int32_t> current_target(const std::filesystem::path& device = kDevice);

  bool held() const { return fd_.valid(); }
  /// Gives the request back (closes the file).
  void release() { fd_.reset(); }

 private:
  UniqueFd fd_;
};

}  // namespace lipdrive
