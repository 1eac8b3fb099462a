#include "firmware_app/outputs/gpio_output.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <exception>
#include <stdexcept>
#include <utility>
#include <vector>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;

constexpr auto kRetryFirst = 100ms;
constexpr auto kRetryMax = 5s;

std::string describe_lines(const GpioLines& lines, const GpioOptions& options) {
  std::string used;
  const auto add = [&](const char* role, const std::string& line) {
    if (!line.empty()) used += (used.empty() ? "" : ", ") + std::string(role) + " " + line;
  };
  add("status", options.status_line);
  add("fault", options.fault_line);
  add("calibrate", options.calibrate_button);
  add("record", options.record_button);
  add("enable", options.enable_switch);
  return lines.describe() + " (" + (used.empty() ? "no lines" : used) + ")";
}

Debouncer debouncer_for(const GpioOptions& options) {
  return Debouncer(std::int64_t{std::max(options.debounce_ms, 0)} * 1'000'000);
}

}  // namespace

std::vector<GpioLineSpec> gpio_line_specs(const GpioOptions& options) {
  std::vector<GpioLineSpec> specs;
  for (const std::string* line : {&options.status_line, &options.fault_line})
    if (!line->empty()) specs.push_back({*line, GpioDirection::kOutput, false});
  for (const std::string* line : {&options.calibrate_button, &options.record_button, &options.enable_switch})
    if (!line->empty()) specs.push_back({*line, GpioDirection::kInput, options.buttons_active_low, options.input_bias});
  return specs;
}

std::unique_ptr<GpioLines> open_gpio_chip(const GpioOptions& options) {
  return open_gpiod_chip(options.chip, gpio_line_specs(options));
}

void check_gpio_chip(const GpioOptions& options) { check_gpiod_chip(options.chip, gpio_line_specs(options)); }

GpioOutput::GpioOutput(const GpioOptions& options, std::unique_ptr<GpioLines> lines, DriveControl& control)
    : lines_(std::move(lines)),
      control_(control),
      status_{options.status_line, std::nullopt},
      fault_{options.fault_line, std::nullopt},
      calibrate_{options.calibrate_button, debouncer_for(options)},
      record_{options.record_button, debouncer_for(options)},
      enable_{options.enable_switch, debouncer_for(options)},
      retry_(kRetryFirst, kRetryMax) {
  if (!lines_) throw std::invalid_argument("GpioOutput needs the lines of a chip");
  description_ = describe_lines(*lines_, options);
  // Open until the first sample says otherwise.
  if (!enable_.line.empty()) control_.enable_switch_closed.store(false);
}

void GpioOutput::publish(const DriveFrame& frame) {
  if (!healthy() && (frame.time_ns < next_retry_ns_ || !reopen_lines(frame.time_ns))) return;
  try {
    const bool tracking = frame.status & kStatusTracking;
    const bool fail_safe = frame.status & kStatusFailSafe;
    const bool camera = frame.status & kStatusCameraConnected;
    const bool enabled = frame.status & kStatusOutputsEnabled;
    write(status_, tracking && !fail_safe);
    write(fault_, (fail_safe && enabled) || !camera);
    poll_buttons(frame.time_ns, frame.status & kStatusRecording);
    poll_enable_switch(frame.time_ns);
  } catch (const std::exception& error) {
    lose_lines(error.what(), frame.time_ns);
  }
}

void GpioOutput::write(OutputLine& output, bool active) {
  if (output.line.empty() || output.written == active) return;
  // Unknown until the write succeeds: a failed write is repeated after recovery.
  output.written.reset();
  lines_->set_output(output.line, active);
  output.written = active;
}

bool GpioOutput::pressed(Button& button, std::int64_t now_ns) {
  return !button.line.empty() && button.debouncer.press(lines_->read_input(button.line), now_ns);
}

void GpioOutput::poll_buttons(std::int64_t now_ns, bool recording) {
  if (pressed(calibrate_, now_ns)) {
    control_.calibrate_requests.fetch_add(1);
    spdlog::info("{}: calibrate button pressed", description_);
  }
  if (pressed(record_, now_ns)) {
    control_.recording_request.store(recording ? 0 : 1);
    spdlog::info("{}: record button pressed: {} the take", description_, recording ? "stop" : "start");
  }
}

void GpioOutput::poll_enable_switch(std::int64_t now_ns) {
  if (enable_.line.empty()) return;
  enable_.debouncer.press(lines_->read_input(enable_.line), now_ns);
  set_enable_switch(enable_.debouncer.level(), "open");
}

void GpioOutput::set_enable_switch(bool closed, const char* why) {
  if (enable_.line.empty() || control_.enable_switch_closed.exchange(closed) == closed) return;
  if (closed)
    spdlog::info("{}: enable switch closed: the drive follows the face", description_);
  else
    spdlog::warn("{}: enable switch {}: the drive eases to neutral", description_, why);
}

void GpioOutput::lose_lines(const char* error, std::int64_t now_ns) {
  spdlog::error("{}: {}; retrying in the background", description_, error);
  set_enable_switch(false, "unreadable");
  healthy_.store(false);
  retry_.succeeded();  // every outage starts at the first delay
  next_retry_ns_ = now_ns + retry_.failed().count();
}

bool GpioOutput::reopen_lines(std::int64_t now_ns) {
  try {
    lines_->reopen();
  } catch (const std::exception& error) {
    // Logged once when the lines were lost; a failing retry is the expected state until the
    // chip returns.
    spdlog::debug("{}: reopen failed: {}", description_, error.what());
    next_retry_ns_ = now_ns + retry_.failed().count();
    return false;
  }
  spdlog::info("{}: lines are back", description_);
  status_.written.reset();
  fault_.written.reset();
  calibrate_.debouncer.reset();
  record_.debouncer.reset();
  enable_.debouncer.reset();
  healthy_.store(true);
  return true;
}

}  // namespace lipdrive
