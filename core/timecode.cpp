#include "core/timecode.hpp"

#include <cmath>

namespace lipdrive {
namespace {

constexpr std::int64_t kNsPerSecond = 1'000'000'000;

// Drop-frame numbering at 30 labels per second: 2 numbers dropped in 9 of every 10 minutes.
constexpr std::int64_t kDropped = 2;
constexpr std::int64_t kLabelsPerMinute = 30 * 60;                                  // 1800
constexpr std::int64_t kFramesPerDropMinute = kLabelsPerMinute - kDropped;          // 1798
constexpr std::int64_t kFramesPer10Minutes = 10 * kLabelsPerMinute - 9 * kDropped;  // 17982

/// Floor division for a positive divisor.
std::int64_t floor_div(std::int64_t a, std::int64_t b) { return a / b - (a % b != 0 && a < 0); }

std::int64_t wrap(std::int64_t frame, TimecodeRate rate) {
  const std::int64_t day = frames_per_day(rate);
  return ((frame % day) + day) % day;
}

std::optional<int> two_digits(std::string_view text, std::size_t at) {
  const char a = text[at], b = text[at + 1];
  if (a < '0' || a > '9' || b < '0' || b > '9') return std::nullopt;
  return (a - '0') * 10 + (b - '0');
}

void put_two_digits(char* out, int value) {
  out[0] = static_cast<char>('0' + value / 10 % 10);
  out[1] = static_cast<char>('0' + value % 10);
}

}  // namespace

FrameRate frame_rate(TimecodeRate rate) {
  switch (rate) {
    case TimecodeRate::k24: return {24, 1};
    case TimecodeRate::k25: return {25, 1};
    case TimecodeRate::k29_97DropFrame: return {30000, 1001};
    case TimecodeRate::k30: return {30, 1};
  }
  return {25, 1};
}

int label_fps(TimecodeRate rate) {
  switch (rate) {
    case TimecodeRate::k24: return 24;
    case TimecodeRate::k25: return 25;
    case TimecodeRate::k29_97DropFrame:
    case TimecodeRate::k30: return 30;
  }
  return 25;
}

bool is_drop_frame(TimecodeRate rate) { return rate == TimecodeRate::k29_97DropFrame; }

std::string_view rate_name(TimecodeRate rate) {
  switch (rate) {
    case TimecodeRate::k24: return "24";
    case TimecodeRate::k25: return "25";
    case TimecodeRate::k29_97DropFrame: return "29.97";
    case TimecodeRate::k30: return "30";
  }
  return "25";
}

std::optional<TimecodeRate> rate_from_fps(double fps) {
  for (const TimecodeRate rate :
       {TimecodeRate::k24, TimecodeRate::k25, TimecodeRate::k29_97DropFrame, TimecodeRate::k30}) {
    const double nominal = rate == TimecodeRate::k29_97DropFrame ? 29.97 : label_fps(rate);
    if (std::abs(fps - nominal) < 0.001) return rate;
  }
  return std::nullopt;
}

std::int32_t frames_per_day(TimecodeRate rate) {
  if (is_drop_frame(rate)) return static_cast<std::int32_t>(24 * 6 * kFramesPer10Minutes);
  return 24 * 3600 * label_fps(rate);
}

Timecode timecode_from_frame(std::int64_t frame, TimecodeRate rate) {
  std::int64_t label = wrap(frame, rate);  // counts every label, dropped ones included
  const int fps = label_fps(rate);
  if (is_drop_frame(rate)) {
    // Add back the numbers skipped before this frame: 18 per whole ten minutes, and 2 per
    // minute begun after the first minute of the current ten.
    const std::int64_t tens = label / kFramesPer10Minutes, rest = label % kFramesPer10Minutes;
    label += 9 * kDropped * tens;
    if (rest >= kDropped) label += kDropped * ((rest - kDropped) / kFramesPerDropMinute);
  }
  Timecode t;
  t.frames = static_cast<int>(label % fps);
  t.seconds = static_cast<int>(label / fps % 60);
  t.minutes = static_cast<int>(label / (fps * 60) % 60);
  t.hours = static_cast<int>(label / (std::int64_t{fps} * 3600) % 24);
  return t;
}

std::optional<std::int32_t> frame_from_timecode(const Timecode& t, TimecodeRate rate) {
  const int fps = label_fps(rate);
  if (t.hours < 0 || t.hours > 23 || t.minutes < 0 || t.minutes > 59 || t.seconds < 0 || t.seconds > 59 ||
      t.frames < 0 || t.frames >= fps)
    return std::nullopt;
  std::int64_t label = ((std::int64_t{t.hours} * 60 + t.minutes) * 60 + t.seconds) * fps + t.frames;
  if (is_drop_frame(rate)) {
    if (t.seconds == 0 && t.frames < kDropped && t.minutes % 10 != 0) return std::nullopt;
    const std::int64_t minutes = std::int64_t{t.hours} * 60 + t.minutes;
    label -= kDropped * (minutes - minutes / 10);
  }
  return static_cast<std::int32_t>(label);
}

std::optional<Timecode> parse_timecode(std::string_view text) {
  if (text.size() != 11 || text[2] != ':' || text[5] != ':') return std::nullopt;
  const char last = text[8];
  if (last != ':' && last != ';' && last != '.') return std::nullopt;
  const auto h = two_digits(text, 0), m = two_digits(text, 3), s = two_digits(text, 6), f = two_digits(text, 9);
  if (!h || !m || !s || !f) return std::nullopt;
  return Timecode{*h, *m, *s, *f};
}

TimecodeText format_timecode(const Timecode& t, TimecodeRate rate) {
  TimecodeText text;
  char* out = text.chars.data();
  put_two_digits(out, t.hours);
  out[2] = ':';
  put_two_digits(out + 3, t.minutes);
  out[5] = ':';
  put_two_digits(out + 6, t.seconds);
  out[8] = is_drop_frame(rate) ? ';' : ':';
  put_two_digits(out + 9, t.frames);
  return text;
}

TimecodeText format_frame(std::int64_t frame, TimecodeRate rate) {
  return format_timecode(timecode_from_frame(frame, rate), rate);
}

std::int32_t frame_after(std::int64_t start, std::int64_t elapsed_ns, TimecodeRate rate) {
  const FrameRate r = frame_rate(rate);
  // |elapsed| < 24 h = 8.64e13 ns, times at most 30000: below 2.6e18, inside int64.
  const std::int64_t frames = floor_div(elapsed_ns * r.numerator, kNsPerSecond * r.denominator);
  return static_cast<std::int32_t>(wrap(start + frames, rate));
}

std::int64_t frame_start_ns(std::int64_t frame, TimecodeRate rate) {
  const FrameRate r = frame_rate(rate);
  // Split into whole seconds' worth of frames and the rest so the product stays small.
  const std::int64_t per = r.numerator;  // frames in `denominator` seconds
  return frame / per * r.denominator * kNsPerSecond + frame % per * r.denominator * kNsPerSecond / r.numerator;
}

}  // namespace lipdrive
