#include "firmware_app/outputs/modbus_client_output.hpp"

#include "drivers/clock.hpp"
#include "firmware_app/outputs/modbus_registers.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <stdexcept>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;

constexpr auto kFirstBackoff = 100ms;
// How often the client thread looks for a newer frame (and for destruction) while idle.
constexpr auto kFramePoll = 20ms;

}  // namespace

ModbusClientOutput::ModbusClientOutput(const ModbusClientOptions& options, std::span<const ChannelSpec> channels)
    : options_(options),
      channel_indices_(pick_channels(options.channels, channels, "modbus client")),
      description_(fmt::format("modbus client {} registers {}..{}", lipdrive::describe(options.link),
                               options.first_register,
                               options.first_register + static_cast<int>(channel_indices_.size()) - 1)),
      client_(options.link, std::chrono::milliseconds(options.timeout_ms)),
      backoff_(kFirstBackoff, std::chrono::milliseconds(options.max_backoff_ms)) {
  const int count = static_cast<int>(channel_indices_.size());
  if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || count > kMaxChannels || options.first_register < 0 ||
      options.first_register + count > 65536)
    throw std::invalid_argument(fmt::format("{}: {} channels do not fit in one write request", description_, count));
  thread_ = std::thread(&ModbusClientOutput::run, this);
}

ModbusClientOutput::~ModbusClientOutput() {
  {
    std::lock_guard lock(stop_mutex_);
    stopping_ = true;
  }
  stop_wake_.notify_all();
  thread_.join();
}

bool ModbusClientOutput::sleep_until(std::int64_t deadline_ns) {
  std::unique_lock lock(stop_mutex_);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(deadline_ns - monotonic_ns());
  return !stop_wake_.wait_until(lock, deadline, [this] { return stopping_; });
}

bool ModbusClientOutput::write(const DriveFrame& frame) {
  std::array<std::uint16_t, kMaxChannels> registers{};
  for (std::size_t i = 0; i < channel_indices_.size(); ++i)
    registers[i] = to_register(frame.values[static_cast<std::size_t>(channel_indices_[i])]);
  const bool ok = client_.write_registers(options_.first_register, {registers.data(), channel_indices_.size()});
  connected_.store(client_.connected(), std::memory_order_relaxed);
  if (!ok) {
    writes_failed_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  writes_ok_.fetch_add(1, std::memory_order_relaxed);
  // Idle ticks repeat the capture time of the last result: count each capture once.
  if (frame.capture_time_ns > 0 && frame.sequence != last_sequence_on_wire_) {
    wire_latency_.add(monotonic_ns() - frame.capture_time_ns);
    last_sequence_on_wire_ = frame.sequence;
  }
  return true;
}

void ModbusClientOutput::run() {
  const std::int64_t period_ns = 1'000'000'000 / std::max(options_.rate_hz, 1);
  DriveFrame frame;
  std::uint32_t written = 0;
  std::uint64_t failed_in_outage = 0;
  for (;;) {
    {
      std::lock_guard lock(stop_mutex_);
      if (stopping_) break;
    }
    latest_.wait_newer(written, kFramePoll);
    const std::uint32_t version = latest_.read(frame);
    if (version == written) continue;
    const std::int64_t attempt_ns = monotonic_ns();
    if (write(frame)) {
      written = version;
      if (backoff_.failing())
        spdlog::info("{}: writing again after {} failed attempts", description_, failed_in_outage);
      backoff_.succeeded();
      failed_in_outage = 0;
      if (!sleep_until(attempt_ns + period_ns)) break;
      continue;
    }
    if (!backoff_.failing())
      spdlog::warn("{}: {}; retrying with back-off up to {} ms", description_, client_.last_error(),
                   options_.max_backoff_ms);
    ++failed_in_outage;
    if (!sleep_until(monotonic_ns() + backoff_.failed().count())) break;
  }
  // The pipeline's last frame is the neutral pose: make sure it went out.
  if (latest_.read(frame) != written) write(frame);
  client_.disconnect();
  connected_.store(false, std::memory_order_relaxed);
}

}  // namespace lipdrive
