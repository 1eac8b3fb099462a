#include "firmware_app/outputs/sender_output.hpp"

#include "drivers/clock.hpp"
#include "drivers/thread_scheduling.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;

constexpr auto kFirstBackoff = 100ms;
// How often the sender thread looks for a newer frame (and for stop()) while idle.
constexpr auto kFramePoll = 20ms;

}  // namespace

SenderOutput::SenderOutput(std::string description, int rate_hz, std::chrono::milliseconds max_backoff)
    : description_(std::move(description)),
      period_ns_(1'000'000'000 / std::max(rate_hz, 1)),
      backoff_(kFirstBackoff, max_backoff) {}

void SenderOutput::start() {
  thread_ = std::thread(&SenderOutput::run, this);
  // "lipdrive-dmx", "lipdrive-osc", ...: the description's first word.
  name_thread(thread_, ("lipdrive-" + description_.substr(0, description_.find(' '))).c_str());
}

void SenderOutput::request_stop() {
  {
    std::lock_guard lock(stop_mutex_);
    stopping_ = true;
  }
  stop_wake_.notify_all();
}

void SenderOutput::stop() {
  request_stop();
  if (thread_.joinable()) thread_.join();
}

bool SenderOutput::sleep_until(std::int64_t deadline_ns) {
  std::unique_lock lock(stop_mutex_);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(deadline_ns - monotonic_ns());
  return !stop_wake_.wait_until(lock, deadline, [this] { return stopping_; });
}

bool SenderOutput::send_counted(const DriveFrame& frame) {
  const bool ok = send(frame);
  healthy_.store(ok, std::memory_order_relaxed);
  if (!ok) {
    sends_failed_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  sends_ok_.fetch_add(1, std::memory_order_relaxed);
  // Idle ticks repeat the capture time of the last result: count each capture once.
  if (frame.capture_time_ns > 0 && frame.sequence != last_sequence_on_wire_) {
    wire_latency_.add(monotonic_ns() - frame.capture_time_ns);
    last_sequence_on_wire_ = frame.sequence;
  }
  return true;
}

void SenderOutput::run() {
  DriveFrame frame;
  std::uint32_t sent = 0;
  std::uint64_t failed_in_outage = 0;
  for (;;) {
    {
      std::lock_guard lock(stop_mutex_);
      if (stopping_) break;
    }
    latest_.wait_newer(sent, kFramePoll);
    const std::uint32_t version = latest_.read(frame);
    if (version == sent) continue;
    const std::int64_t attempt_ns = monotonic_ns();
    if (send_counted(frame)) {
      sent = version;
      if (backoff_.failing())
        spdlog::info("{}: sending again after {} failed attempts", description_, failed_in_outage);
      backoff_.succeeded();
      failed_in_outage = 0;
      if (!sleep_until(attempt_ns + period_ns_)) break;
      continue;
    }
    if (!backoff_.failing())
      spdlog::warn("{}: {}; retrying with back-off up to {} ms", description_, failure(),
                   std::chrono::duration_cast<std::chrono::milliseconds>(backoff_.max()).count());
    ++failed_in_outage;
    if (!sleep_until(monotonic_ns() + backoff_.failed().count())) break;
  }
  // The pipeline's last frame (the neutral pose; at a reload the figure where it is): make sure
  // it went out, unless a peer this waits for failed the last attempt: one more would hold the
  // stop for the link's whole timeout (a Modbus slave that stopped answering: timeout_ms), and
  // the service's stop is bounded.
  if (latest_.read(frame) != sent && ((backoff_.failing() && send_waits_for_peer()) || !send_counted(frame)))
    spdlog::warn("{}: {}; the neutral pose was not sent", description_, failure());
  close();
  healthy_.store(false, std::memory_order_relaxed);
}

}  // namespace lipdrive
