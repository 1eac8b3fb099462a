#include "firmware_app/outputs/serial_output.hpp"

#include "drivers/clock.hpp"
#include "drivers/serial_protocol.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstring>
#include <set>
#include <stdexcept>
#include <thread>

namespace lipdrive {
namespace {

namespace wire = serial_protocol;

constexpr std::chrono::milliseconds kFirstBackoff{100};
constexpr int kMaxServo = 23;  // the largest Mini Maestro has 24 channels

const char* mode_name(SerialOutputOptions::Mode mode) {
  switch (mode) {
    case SerialOutputOptions::Mode::kFramed: return "framed";
    case SerialOutputOptions::Mode::kLine: return "line";
    case SerialOutputOptions::Mode::kMaestro: return "maestro";
  }
  return "?";
}

void check_line_name(const std::string& name) {
  if (name.empty() || name.find_first_of(" =\r\n") != std::string::npos)
    throw std::invalid_argument("serial output (line mode): channel name '" + name +
                                "' cannot be sent: it is empty or contains a space, '=' or a line break");
}

void check_servo_channel(const ChannelSpec& channel, int servo, std::set<int>& used) {
  const std::string what =
      "serial output (maestro): servo " + std::to_string(servo) + " on channel '" + channel.name + "'";
  if (servo < 0 || servo > kMaxServo) throw std::invalid_argument(what + ": servo number outside 0..23");
  if (!used.insert(servo).second) throw std::invalid_argument(what + ": servo number used twice");
  const double max_us = wire::kMaestroMaxTarget / 4.0;
  if (!(channel.out_min > 0 && channel.out_max > 0 && channel.out_min <= max_us && channel.out_max <= max_us))
    throw std::invalid_argument(what + ": the channel's output range " + std::to_string(channel.out_min) + ".." +
                                std::to_string(channel.out_max) +
                                " is not a pulse width in microseconds within (0, 4095.75]");
}

}  // namespace

SerialOutput::SerialOutput(const SerialOutputOptions& options, std::span<const ChannelSpec> channels)
    : mode_(options.mode),
      settings_(options.line),
      description_(std::string("serial ") + mode_name(options.mode) + " " + describe_serial_settings(settings_)),
      backoff_(kFirstBackoff, std::chrono::milliseconds(options.max_backoff_ms)) {
  validate_serial_settings(settings_);
  if (options.max_backoff_ms < 1) throw std::invalid_argument("serial output: max_backoff_ms must be at least 1");

  std::size_t frame_bytes = 0;
  if (mode_ == SerialOutputOptions::Mode::kMaestro) {
    if (options.servos.empty()) throw std::invalid_argument("serial output (maestro): no servos configured");
    std::set<int> used;
    for (const auto& servo : options.servos) {
      const int index = pick_channels(std::span(&servo.channel, 1), channels, "serial output").front();
      check_servo_channel(channels[static_cast<std::size_t>(index)], servo.servo, used);
      channel_indices_.push_back(index);
      servos_.push_back(servo.servo);
    }
    frame_bytes = wire::kMaestroCommandBytes * servos_.size();
  } else {
    channel_indices_ = pick_channels(options.channels, channels, "serial output");
    if (channel_indices_.size() > wire::kMaxFrameChannels)
      throw std::invalid_argument("serial output: more than 32 channels");
    if (mode_ == SerialOutputOptions::Mode::kLine) {
      for (int index : channel_indices_) {
        names_.push_back(channels[static_cast<std::size_t>(index)].name);
        check_line_name(names_.back());
      }
      frame_bytes = wire::line_size_bound(names_);
    } else {
      frame_bytes = wire::framed_size(channel_indices_.size());
    }
  }
  picked_.resize(channel_indices_.size());
  buffer_.resize(frame_bytes);
  try_open(monotonic_ns());
}

SerialOutputCounters SerialOutput::counters() const {
  return {written_.load(std::memory_order_relaxed), dropped_.load(std::memory_order_relaxed),
          offline_.load(std::memory_order_relaxed), reopens_.load(std::memory_order_relaxed)};
}

void SerialOutput::publish(const DriveFrame& frame) {
  const std::int64_t now_ns = monotonic_ns();
  if (!port_ && !reopen_due(now_ns)) {
    offline_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  // Finish a frame the kernel took only part of before starting a new one.
  if (pending_begin_ < pending_end_ && !write_pending()) {
    (port_ ? dropped_ : offline_).fetch_add(1, std::memory_order_relaxed);
    return;
  }
  // A frame's worth still unsent in the kernel means the line is slower than the frame rate;
  // queueing more would only add latency, and the next tick brings newer values anyway.
  if (port_->queued_bytes() >= buffer_.size()) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  pending_begin_ = 0;
  pending_end_ = encode(frame);
  pending_capture_ns_ = frame.new_result ? frame.capture_time_ns : 0;
  pending_counter_ = frame.counter;
  if (write_pending()) return;
  if (!port_) {
    offline_.fetch_add(1, std::memory_order_relaxed);
  } else if (pending_begin_ == 0) {
    // Nothing of it was taken: drop it whole rather than finish a stale frame later.
    pending_end_ = 0;
    dropped_.fetch_add(1, std::memory_order_relaxed);
  }
}

void SerialOutput::publish_last(const DriveFrame& frame) {
  const std::int64_t deadline_ns = monotonic_ns() + 200'000'000;
  for (;;) {
    publish(frame);
    if (last_written_counter_ == frame.counter) return;
    if (monotonic_ns() > deadline_ns) {
      spdlog::warn("{}: the neutral pose was not sent ({})", describe(),
                   port_ ? "the line did not take it within 200 ms" : "the line is gone");
      return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
}

std::size_t SerialOutput::encode(const DriveFrame& frame) {
  for (std::size_t i = 0; i < channel_indices_.size(); ++i)
    picked_[i] = frame.values[static_cast<std::size_t>(channel_indices_[i])];
  switch (mode_) {
    case SerialOutputOptions::Mode::kFramed: {
      const wire::FrameHeader header{static_cast<std::uint16_t>(frame.counter),
                                     static_cast<std::uint32_t>(frame.time_ns / 1000), frame.status};
      return wire::encode_framed(header, picked_, buffer_);
    }
    case SerialOutputOptions::Mode::kLine: return wire::encode_line(names_, picked_, buffer_);
    case SerialOutputOptions::Mode::kMaestro: return wire::encode_maestro(servos_, picked_, buffer_);
  }
  return 0;
}

bool SerialOutput::write_pending() {
  const auto result = port_->write_some(std::span(buffer_).subspan(pending_begin_, pending_end_ - pending_begin_));
  if (result.status == SerialPort::WriteStatus::kGone) {
    port_.reset();
    pending_begin_ = pending_end_ = 0;  // a torn frame: receivers resynchronise on the next one
    begin_outage(std::string("write failed: ") + std::strerror(result.error), monotonic_ns());
    return false;
  }
  pending_begin_ += result.written;
  if (pending_begin_ < pending_end_) return false;
  const std::int64_t wire_ns = monotonic_ns();
  written_.fetch_add(1, std::memory_order_relaxed);
  last_written_counter_ = pending_counter_;
  if (pending_capture_ns_ > 0) latency_.add(wire_ns - pending_capture_ns_);
  return true;
}

bool SerialOutput::reopen_due(std::int64_t now_ns) {
  if (now_ns < next_open_ns_) return false;
  try_open(now_ns);
  return port_ != nullptr;
}

void SerialOutput::try_open(std::int64_t now_ns) {
  try {
    port_ = std::make_unique<SerialPort>(settings_);
  } catch (const SerialPortError& error) {
    if (!in_outage_) {
      begin_outage(error.what(), now_ns);
    } else {
      next_open_ns_ = now_ns + backoff_.failed().count();
      spdlog::debug("{}: {}; next attempt in {} ms", description_, error.what(), backoff_.delay().count() / 1'000'000);
    }
    return;
  }
  if (settings_.rs485 && !port_->rs485_active())
    spdlog::warn("{}: the driver refuses RS-485 mode ({}); the transceiver must switch direction by itself",
                 description_, port_->rs485_refusal());
  backoff_.succeeded();
  if (in_outage_) {
    in_outage_ = false;
    reopens_.fetch_add(1, std::memory_order_relaxed);
    spdlog::info("{}: reopened after {} ms ({} frames not sent)", description_, (now_ns - outage_start_ns_) / 1'000'000,
                 offline_.load(std::memory_order_relaxed) - offline_at_outage_start_);
  } else {
    spdlog::info("{}: open", description_);
  }
  healthy_.store(true, std::memory_order_relaxed);
}

void SerialOutput::begin_outage(const std::string& reason, std::int64_t now_ns) {
  in_outage_ = true;
  healthy_.store(false, std::memory_order_relaxed);
  outage_start_ns_ = now_ns;
  offline_at_outage_start_ = offline_.load(std::memory_order_relaxed);
  backoff_.succeeded();  // every outage starts at the first delay
  next_open_ns_ = now_ns + backoff_.failed().count();
  spdlog::error("{}: {}; retrying with back-off up to {} ms", description_, reason, backoff_.max().count() / 1'000'000);
}

}  // namespace lipdrive
