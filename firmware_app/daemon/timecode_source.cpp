#include "firmware_app/daemon/timecode_source.hpp"

#include "drivers/clock.hpp"

#include <fmt/format.h>

#include <ctime>

namespace lipdrive {
namespace {

constexpr std::int64_t kNsPerSecond = 1'000'000'000;
constexpr std::int64_t kNsPerDay = 86'400 * kNsPerSecond;
// No good LTC frame for this long: absent.
constexpr std::int64_t kLtcAbsentNs = 500'000'000;
// A rejected frame shows on the status line for this long.
constexpr std::int64_t kLtcGarbledNs = 2 * kNsPerSecond;

std::int64_t local_utc_offset_ns() {
  const std::time_t now = std::time(nullptr);
  std::tm local{};
  ::localtime_r(&now, &local);
  return static_cast<std::int64_t>(local.tm_gmtoff) * kNsPerSecond;
}

}  // namespace

ClockTimecode::ClockTimecode(TimecodeRate rate) : TimecodeSource(rate), utc_offset_ns_(local_utc_offset_ns()) {}

std::optional<std::int32_t> ClockTimecode::frame_at(std::int64_t capture_time_ns) const {
  const std::int64_t local = wall_time_ns(capture_time_ns) + utc_offset_ns_;
  const std::int64_t since_midnight = ((local % kNsPerDay) + kNsPerDay) % kNsPerDay;
  return frame_after(0, since_midnight, rate());
}

std::string ClockTimecode::describe() const {
  return fmt::format("system clock time of day at {} fps", rate_name(rate()));
}

LtcTimecode::LtcTimecode(std::unique_ptr<AudioSource> input, TimecodeRate rate, int realtime_priority)
    : TimecodeSource(rate),
      decoder_(input->sample_rate(), frame_rate(rate).fps()),
      listener_(std::move(input), "lipdrive-ltc", realtime_priority, [this](const AudioBlock& block) { hear(block); }) {
}

void LtcTimecode::hear(const AudioBlock& block) {
  decoder_.write({block.samples.data(), static_cast<std::size_t>(block.frames)}, block.sample_rate,
                 block.capture_time_ns);
  for (LtcFrame frame; decoder_.read(frame);) take(frame);
}

void LtcTimecode::take(const LtcFrame& frame) {
  decoded_.fetch_add(1, std::memory_order_relaxed);
  const auto number = frame_from_timecode({frame.hours, frame.minutes, frame.seconds, frame.frames}, rate());
  const bool follows = number && last_ && *number == static_cast<std::int32_t>((*last_ + 1) % frames_per_day(rate()));
  if (!number || frame.drop_frame != is_drop_frame(rate()) || frame.reverse || (last_ && !follows)) {
    rejected_.fetch_add(1, std::memory_order_relaxed);
    last_rejected_ns_.store(monotonic_ns(), std::memory_order_relaxed);
  }
  last_ = number;
  if (follows && frame.drop_frame == is_drop_frame(rate()) && !frame.reverse)
    anchor_.publish({*number, frame.start_time_ns});
}

std::optional<std::int32_t> LtcTimecode::frame_at(std::int64_t capture_time_ns) const {
  Anchor anchor;
  if (anchor_.read(anchor) == 0) return std::nullopt;
  const std::int64_t since = capture_time_ns - anchor.start_ns;
  // The newest frame is decoded once it has ended: frames captured up to a few frame
  // periods after its start are normal; far from it, LTC has stopped.
  if (since > kLtcAbsentNs || since < -kLtcAbsentNs) return std::nullopt;
  return frame_after(anchor.frame, since, rate());
}

std::string LtcTimecode::problem() const {
  const std::int64_t now = monotonic_ns();
  if (listener_.input_lost()) return fmt::format("LTC input {} lost", listener_.input_name());
  // A signal that decodes into rejected frames is there but wrong: say so rather than absent.
  if (now - last_rejected_ns_.load(std::memory_order_relaxed) < kLtcGarbledNs)
    return fmt::format("LTC garbled on {} ({} of {} frames rejected)", listener_.input_name(), frames_rejected(),
                       frames_decoded());
  Anchor anchor;
  if (anchor_.read(anchor) == 0 || now - anchor.start_ns > kLtcAbsentNs)
    return fmt::format("no LTC on {}: frames are not stamped", listener_.input_name());
  return {};
}

std::string LtcTimecode::describe() const {
  return fmt::format("LTC at {} fps from {}", rate_name(rate()), listener_.input_name());
}

}  // namespace lipdrive
