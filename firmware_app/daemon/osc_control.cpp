#include "firmware_app/daemon/osc_control.hpp"

#include "core/osc_addresses.hpp"
#include "drivers/thread_scheduling.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <chrono>

namespace lipdrive {
namespace {

// How often the thread looks at stop_ while nothing arrives.
constexpr std::chrono::milliseconds kPoll{100};

/// A slate as a file-name part: letters, digits, '-', '.' and '_' kept, everything else '_'.
std::string file_name_part(std::string_view text) {
  std::string part(text.substr(0, 64));
  std::ranges::replace_if(
      part, [](char c) { return !(std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '.' || c == '_'); },
      '_');
  if (!part.empty() && part.front() == '.') part.front() = '_';
  return part;
}

}  // namespace

OscControl::OscControl(const std::string& address, int port, DriveControl& control)
    : receiver_(address, port), control_(control), thread_(&OscControl::run, this) {
  name_thread(thread_, "lipdrive-oscctl");
}

OscControl::~OscControl() {
  stop_ = true;
  thread_.join();
}

std::optional<std::string> OscControl::next_take_name() {
  std::lock_guard lock(mutex_);
  if (slate_.empty()) return std::nullopt;
  return slate_ + "_" + std::to_string(take_++);
}

void OscControl::run() {
  std::string from;
  while (!stop_.load(std::memory_order_relaxed)) {
    const auto received = receiver_.receive(
        kPoll, [this](const OscMessage& m) { handle(m); }, &from);
    const bool malformed = received == OscReceiver::Received::kMalformed;
    if (std::uint64_t held = 0; (malformed || received == OscReceiver::Received::kBundle) && refused_log_.pass(held))
      spdlog::warn("{}: {} from {}{}", describe(),
                   malformed ? "a malformed OSC datagram" : "a bundle (send commands as single messages)", from,
                   held_back_note(held));
  }
  refused_log_.log_held_back(describe() + ": malformed datagrams and bundles");
  for (LogThrottle& log : command_log_) log.log_held_back(describe() + ": commands");
}

void OscControl::handle(const OscMessage& m) {
  const std::string_view address = m.address();
  const auto set_slate = [&](int at) {
    if (const auto slate = m.string(at)) {
      std::lock_guard lock(mutex_);
      slate_ = file_name_part(*slate);
    }
  };
  const auto set_take = [&](int at) {
    if (const auto take = m.number(at); take && *take >= 0 && *take < 1e6) {
      std::lock_guard lock(mutex_);
      take_ = static_cast<int>(*take);
    }
  };
  std::size_t command = 0;  // which of command_log_
  if (address == osc::kRecordStart) {
    set_slate(0);
    set_take(1);
    control_.recording_request.store(1, std::memory_order_relaxed);
  } else if (address == osc::kRecordStop) {
    command = 1;
    control_.recording_request.store(0, std::memory_order_relaxed);
  } else if (address == osc::kSlate) {
    command = 2;
    set_slate(0);
  } else if (address == osc::kTake) {
    command = 3;
    set_take(0);
  } else if (address == osc::kCalibrate) {
    command = 4;
    control_.calibrate_requests.fetch_add(1, std::memory_order_relaxed);
  } else if (address == osc::kOutputEnable) {
    command = 5;
    if (const auto on = m.number(0)) control_.outputs_enabled.store(*on != 0, std::memory_order_relaxed);
  } else {
    spdlog::debug("{}: ignored {} ,{}", describe(), address, m.types());
    return;
  }
  if (std::uint64_t held = 0; command_log_[command].pass(held))
    spdlog::info("{}: {} ,{}{}", describe(), address, m.types(), held_back_note(held));
}

}  // namespace lipdrive
