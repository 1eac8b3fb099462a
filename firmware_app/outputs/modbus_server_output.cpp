#include "firmware_app/outputs/modbus_server_output.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lipdrive {
namespace {

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
      server_(
          options.link, options.max_clients, modbus_map::kFirstChannel + channel_count_,
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
  if (frame.timecode >= 0) {
    const Timecode t = timecode_from_frame(frame.timecode, frame.timecode_rate);
    input[kTimecodeHoursMinutes] = static_cast<std::uint16_t>(t.hours << 8 | t.minutes);
    input[kTimecodeSecondsFrames] = static_cast<std::uint16_t>(t.seconds << 8 | t.frames);
    input[kTimecodeState] = static_cast<std::uint16_t>(1 | (is_drop_frame(frame.timecode_rate) ? 2 : 0));
    input[kTimecodeRate] = static_cast<std::uint16_t>(std::lround(frame_rate(frame.timecode_rate).fps() * 100));
  } else {
    for (const int reg : {kTimecodeHoursMinutes, kTimecodeSecondsFrames, kTimecodeState, kTimecodeRate})
      input[static_cast<std::size_t>(reg)] = 0;
  }
  for (int i = 0; i < channel_count_; ++i)
    input[static_cast<std::size_t>(kFirstChannel + i)] = to_register(frame.values[static_cast<std::size_t>(i)]);

  holding[kOutputEnable] = control_.outputs_enabled.load(std::memory_order_relaxed) ? 1 : 0;
  holding[kCalibrate] = 0;
  holding[kRecord] = (frame.status & kStatusRecording) ? 1 : 0;
  // The reserved registers read 0 whatever was written to them (docs/modbus-register-map.md).
  for (int reg = kRecord + 1; reg < kFirstOverride; ++reg) holding[static_cast<std::size_t>(reg)] = 0;
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

}  // namespace lipdrive
