#include "firmware_app/daemon/osc_control.hpp"

#include "core/osc_addresses.hpp"
#include "drivers/thread_scheduling.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>

namespace lipdrive {
namespace {

// How often the thread looks at stop_ while nothing arrives, or while it waits to bind again.
constexpr std::chrono::milliseconds kPoll{100};
// Binding again after a failure: 100 ms, doubling up to 2 s.
constexpr std::chrono::milliseconds kFirstRebind{100}, kMaxRebind{2000};

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
    : address_(address),
      port_(port),
      where_(resolve_udp(address, port).describe()),
      rebind_(kFirstRebind, kMaxRebind),
      control_(control) {
  bind();
  thread_ = std::thread(&OscControl::run, this);
  name_thread(thread_, "lipdrive-oscctl");
}

bool OscControl::bind() {
  const bool failing = rebind_.failing();
  try {
    receiver_.emplace(address_, port_);
  } catch (const UdpError& e) {
    rebind_.failed();
    if (!failing)
      spdlog::error("{}: {}; trying again with back-off up to {} ms, the daemon runs on without OSC control until then",
                    describe(), e.what(), kMaxRebind.count());
    return false;
  }
  bound_port_.store(receiver_->port(), std::memory_order_relaxed);
  if (failing) spdlog::info("{}: bound; OSC control again", describe());
  rebind_.succeeded();
  return true;
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
  auto next_bind = std::chrono::steady_clock::now() + rebind_.delay();
  while (!stop_.load(std::memory_order_relaxed)) {
    if (!receiver_) {
      if (std::chrono::steady_clock::now() < next_bind) {
        std::this_thread::sleep_for(kPoll);
      } else if (!bind()) {
        next_bind = std::chrono::steady_clock::now() + rebind_.delay();
      }
      continue;
    }
    const auto received = receiver_->receive(
        kPoll, [this](const OscMessage& m) { handle(m); }, &from);
    const bool malformed = received == OscReceiver::Received::kMalformed;
    if (std::uint64_t held = 0; (malformed || received == OscReceiver::Received::kBundle) && refused_log_.pass(held))
      spdlog::warn("{}: {} from {}{}", describe(),
                   malformed ? "a malformed OSC datagram" : "a bundle (send commands as single messages)", from,
                   held_back_note(held));
  }
  refused_log_.log_held_back(describe() + ": refused datagrams and commands");
  for (LogThrottle& log : command_log_) log.log_held_back(describe() + ": commands");
}

void OscControl::handle(const OscMessage& m) {
  const std::string_view address = m.address();
  // Arguments are checked before anything acts: a command whose argument is of another type or
  // out of its range is refused with the reason, and nothing of it is done (a NaN sent as
  // output_enable does not switch the drive on).
  const auto take_at = [&](int at) -> std::optional<int> {
    const auto take = m.number(at);
    if (!take || !(*take >= 0 && *take < 1e6) || *take != std::floor(*take)) return std::nullopt;
    return static_cast<int>(*take);
  };
  const auto refuse = [&](std::string_view reason) {
    if (std::uint64_t held = 0; refused_log_.pass(held))
      spdlog::warn("{}: {} ,{} refused: {}{}", describe(), address, m.types(), reason, held_back_note(held));
  };
  std::size_t command = 0;  // which of command_log_
  if (address == osc::kRecordStart) {
    const auto slate = m.size() > 0 ? m.string(0) : std::nullopt;
    const auto take = m.size() > 1 ? take_at(1) : std::nullopt;
    if ((m.size() > 0 && !slate) || (m.size() > 1 && !take) || m.size() > 2)
      return refuse("it takes no argument, a slate (s), or a slate and a take number (s i, 0..999999)");
    std::lock_guard lock(mutex_);
    if (slate) slate_ = file_name_part(*slate);
    if (take) take_ = *take;
    control_.recording_request.store(1, std::memory_order_relaxed);
  } else if (address == osc::kRecordStop) {
    command = 1;
    control_.recording_request.store(0, std::memory_order_relaxed);
  } else if (address == osc::kSlate) {
    command = 2;
    const auto slate = m.size() == 1 ? m.string(0) : std::nullopt;
    if (!slate) return refuse("it takes one slate (s)");
    std::lock_guard lock(mutex_);
    slate_ = file_name_part(*slate);
  } else if (address == osc::kTake) {
    command = 3;
    const auto take = m.size() == 1 ? take_at(0) : std::nullopt;
    if (!take) return refuse("it takes one take number (i, 0..999999)");
    std::lock_guard lock(mutex_);
    take_ = *take;
  } else if (address == osc::kCalibrate) {
    command = 4;
    control_.calibrate_requests.fetch_add(1, std::memory_order_relaxed);
  } else if (address == osc::kOutputEnable) {
    command = 5;
    const auto on = m.size() == 1 ? m.number(0) : std::nullopt;
    if (!on || !std::isfinite(*on))
      return refuse("it takes one number (i, f, or T/F): 0 eases to neutral, any other drives");
    control_.outputs_enabled.store(*on != 0, std::memory_order_relaxed);
  } else {
    return refuse("no such command (docs/osc.md lists them)");
  }
  if (std::uint64_t held = 0; command_log_[command].pass(held))
    spdlog::info("{}: {} ,{}{}", describe(), address, m.types(), held_back_note(held));
}

}  // namespace lipdrive
