#include "drivers/cpu_latency.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>

namespace lipdrive {

std::string CpuLatencyRequest::request(int microseconds, const std::filesystem::path& device) {
  release();
  UniqueFd fd(::open(device.c_str(), O_WRONLY | O_CLOEXEC));
  if (!fd.valid()) return fmt::format("{}: {}", device.string(), std::strerror(errno));
  // The kernel reads the value as a binary 32-bit integer.
  const std::int32_t value = microseconds;
  const ssize_t written = ::write(fd.get(), &value, sizeof value);
  if (written != static_cast<ssize_t>(sizeof value))
    return fmt::format("{}: {}", device.string(), written < 0 ? std::strerror(errno) : "short write");
  fd_ = std::move(fd);
  return "";
}

std::optional<std::int32_t> CpuLatencyRequest::current_target(const std::filesystem::path& device) {
  const UniqueFd fd(::open(device.c_str(), O_RDONLY | O_CLOEXEC));
  std::int32_t value = 0;
  if (!fd.valid() || ::read(fd.get(), &value, sizeof value) != static_cast<ssize_t>(sizeof value)) return std::nullopt;
  return value;
}

}  // namespace lipdrive
