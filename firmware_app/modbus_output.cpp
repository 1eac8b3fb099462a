#include "firmware_app/modbus_output.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;

constexpr int kFirstBackoffMs = 100;
// How often the client thread looks for a newer frame (and for destruction) while idle.
constexpr auto kFramePoll = 20ms;

ModbusEndpoint to_endpoint(const ModbusLinkOptions& link) {
  return {.transport = link.transport == ModbusLinkOptions::Transport::kTcp ? ModbusEndpoint::Transport::kTcp
                                                                             : ModbusEndpoint::Transport::kRtu,
          .address = link.address,
          .port = link.port,
          .device = link.line.device.string(),
          .baud = link.line.baud,
          .parity = link.line.parity,
          .data_bits = link.line.data_bits,
          .stop_bits = link.line.stop_bits,
          .rs485 = link.line.rs485,
          .unit_id = link.unit_id};
}

int checked_channel_count(std::span<const ChannelSpec> channels) {
  if (channels.size() > static_cast<std::size_t>(kMaxChannels))
    throw std::invalid_argument(fmt::format("modbus: {} channels, at most {}", channels.size(), kMaxChannels));
  return static_cast<int>(channels.size());
}

/// A 32-bit value as two registers, high word first.
void put_u32(std::span<std::uint16_t> registers, int address, double value) {
  const auto clamped = static_cast<std::uint32_t>(std::clamp(std::round(value), 0.0, 4294967295.0));
  registers[static_cast<std::size_t>(address)] = static_cast<std::uint16_t>(clamped >> 16);
  registers[static_cast<std::size_t>(address) + 1] = static_cast<std::uint16_t>(clamped & 0xFFFF);
}

}  // namespace

std::uint16_t to_register(double value) {
  if (std::isnan(value)) return 0;
  return static_cast<std::uint16_t>(std::clamp(std::round(value), 0.0, 65535.0));
}

// ---------------------------------------------------------------- server

ModbusServerOutput::ModbusServerOutput(const ModbusServerOptions& options, std::span<const ChannelSpec> channels,
                                       DriveControl& control)
    : channel_count_(checked_channel_count(channels)),
      control_(control),
      neutral_frame_([&] {
        DriveFrame neutral;
        neutral.channel_count = channel_count_;
        for (int i = 0; i < channel_count_; ++i)
          neutral.values[static_cast<std::size_t>(i)] = channels[static_cast<std::size_t>(i)].neutral;
        return neutral;
      }()),
      server_(to_endpoint(options.link), options.max_clients, modbus_map::kFirstChannel + channel_count_,
              modbus_map::kFirstOverride + channel_count_,
              [this](std::span<std::uint16_t> input, std::span<std::uint16_t> holding) { refresh(input, holding); },
              [this](int address, std::span<const std::uint16_t> values) { written(address, values); }) {}

void ModbusServerOutput::refresh(std::span<std::uint16_t> input, std::span<std::uint16_t> holding) const {
  using namespace modbus_map;
  DriveFrame frame;
  if (latest_.read(frame) == 0) frame = neutral_frame_;
  input[kStatus] = frame.status;
  input[kHeartbeat] = static_cast<std::uint16_t>(frame.counter & 0xFFFF);
  put_u32(input, kSequenceHigh, static_cast<double>(frame.sequence & 0xFFFF'FFFF));
  put_u32(input, kLatencyUsHigh, static_cast<double>(frame.latency_ms) * 1000);
  input[kFpsTenths] = to_register(static_cast<double>(frame.fps) * 10);
  input[kChannelCount] = static_cast<std::uint16_t>(channel_count_);
  for (int i = 0; i < channel_count_; ++i)
    input[static_cast<std::size_t>(kFirstChannel + i)] = to_register(frame.values[static_cast<std::size_t>(i)]);

  holding[kOutputEnable] = control_.outputs_enabled.load(std::memory_order_relaxed) ? 1 : 0;
  holding[kCalibrate] = 0;
  holding[kRecord] = (control_.daemon_status.load(std::memory_order_relaxed) & kStatusRecording) ? 1 : 0;
  for (int i = 0; i < channel_count_; ++i) {
    const double value = control_.overrides[static_cast<std::size_t>(i)].load(std::memory_order_relaxed);
    holding[static_cast<std::size_t>(kFirstOverride + i)] = std::isnan(value) ? kNoOverride : to_register(value);
  }
}

void ModbusServerOutput::written(int address, std::span<const std::uint16_t> values) {
  using namespace modbus_map;
  for (std::size_t i = 0; i < values.size(); ++i) {
    const int reg = address + static_cast<int>(i);
    const std::uint16_t value = values[i];
    if (reg == kOutputEnable) {
      control_.outputs_enabled.store(value != 0);
    } else if (reg == kCalibrate && value == 1) {
      control_.calibrate_requests.fetch_add(1);
    } else if (reg == kRecord && (value == 0 || value == 1)) {
      control_.recording_request.store(value);
    } else if (reg >= kFirstOverride && reg < kFirstOverride + channel_count_) {
      control_.overrides[static_cast<std::size_t>(reg - kFirstOverride)].store(
          value == kNoOverride ? ChannelBank::kNoOverride : static_cast<double>(value));
    }
  }
}

// ---------------------------------------------------------------- client

namespace {

std::vector<int> channel_indices(const std::vector<std::string>& names, std::span<const ChannelSpec> channels) {
  std::vector<int> indices;
  if (names.empty()) {
    for (int i = 0; i < checked_channel_count(channels); ++i) indices.push_back(i);
    return indices;
  }
  for (const std::string& name : names) {
    const auto found = std::ranges::find(channels, name, &ChannelSpec::name);
    if (found == channels.end()) throw std::invalid_argument(fmt::format("modbus client: unknown channel '{}'", name));
    indices.push_back(static_cast<int>(found - channels.begin()));
  }
  return indices;
}

}  // namespace

ModbusClientOutput::ModbusClientOutput(const ModbusClientOptions& options, std::span<const ChannelSpec> channels)
    : options_(options),
      channel_indices_(channel_indices(options.channels, channels)),
      description_(fmt::format("modbus client {} registers {}..{}", lipdrive::describe(to_endpoint(options.link)),
                               options.first_register,
                               options.first_register + static_cast<int>(channel_indices_.size()) - 1)),
      client_(to_endpoint(options.link), std::chrono::milliseconds(options.timeout_ms)) {
  const int count = static_cast<int>(channel_indices_.size());
  if (count < 1 || count > MODBUS_MAX_WRITE_REGISTERS || options.first_register < 0 ||
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
  const int first_backoff_ms = std::min(kFirstBackoffMs, options_.max_backoff_ms);
  DriveFrame frame;
  std::uint32_t written = 0;
  int backoff_ms = 0;         // 0 while writes succeed
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
      if (backoff_ms > 0)
        spdlog::info("{}: writing again after {} failed attempts", description_, failed_in_outage);
      backoff_ms = 0;
      failed_in_outage = 0;
      if (!sleep_until(attempt_ns + period_ns)) break;
      continue;
    }
    if (backoff_ms == 0)
      spdlog::warn("{}: {}; retrying with back-off up to {} ms", description_, client_.last_error(),
                   options_.max_backoff_ms);
    ++failed_in_outage;
    backoff_ms = backoff_ms == 0 ? first_backoff_ms : std::min(2 * backoff_ms, options_.max_backoff_ms);
    if (!sleep_until(monotonic_ns() + std::int64_t{backoff_ms} * 1'000'000)) break;
  }
  // The pipeline's last frame is the neutral pose: make sure it went out.
  if (latest_.read(frame) != written) write(frame);
  client_.disconnect();
  connected_.store(false, std::memory_order_relaxed);
}

}  // namespace lipdrive
