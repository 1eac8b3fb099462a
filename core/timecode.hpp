// SMPTE timecode (SMPTE ST 12-1): the HH:MM:SS:FF labels of frames at 24, 25, 29.97
// drop-frame and 30 frames per second, the frame number behind a label, and the frame a
// moment falls in. Pure arithmetic on integers: nothing allocates.
//
// A frame number counts frames from 00:00:00:00 and wraps at 24 hours. At 29.97 fps
// (30000/1001 frames per second) the labels count 30 per second but drop the frame numbers
// 00 and 01 at the start of every minute except minutes 00, 10, 20, 30, 40 and 50, so the
// labels stay within 3.6 ms per hour of the clock: 00:00:59;29 is followed by 00:01:00;02.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

namespace lipdrive {

enum class TimecodeRate : std::uint8_t { k24, k25, k29_97DropFrame, k30 };

/// Frames per second as a fraction: 24/1, 25/1, 30000/1001, 30/1.
struct FrameRate {
  std::int64_t numerator = 25, denominator = 1;
  double fps() const { return static_cast<double>(numerator) / static_cast<double>(denominator); }
};

FrameRate frame_rate(TimecodeRate rate);
/// Frames per second the labels count: 24, 25, 30 (drop-frame too) or 30.
int label_fps(TimecodeRate rate);
bool is_drop_frame(TimecodeRate rate);
/// "24", "25", "29.97" or "30".
std::string_view rate_name(TimecodeRate rate);
/// 24, 25, 29.97 (drop-frame) or 30, within 0.001; nullopt for any other rate.
std::optional<TimecodeRate> rate_from_fps(double fps);

/// Frames from 00:00:00:00 to 24:00:00:00: 24 · 3600 · fps, 2,589,408 at 29.97 drop-frame.
std::int32_t frames_per_day(TimecodeRate rate);

/// A label. Which rate it belongs to travels beside it.
struct Timecode {
  int hours = 0, minutes = 0, seconds = 0, frames = 0;
  friend bool operator==(const Timecode&, const Timecode&) = default;
};

/// The label of frame number `frame` (taken modulo frames_per_day, negative numbers too).
Timecode timecode_from_frame(std::int64_t frame, TimecodeRate rate);
/// The frame number of a label; nullopt when the label does not exist at this rate (a field
/// out of range, or a frame number drop-frame skips).
std::optional<std::int32_t> frame_from_timecode(const Timecode& timecode, TimecodeRate rate);

/// "HH:MM:SS:FF"; the separator before the frames may also be ';' or '.' (drop-frame
/// notation) and is not checked against the rate. Field ranges are checked by
/// frame_from_timecode().
std::optional<Timecode> parse_timecode(std::string_view text);

/// "HH:MM:SS:FF", or "HH:MM:SS;FF" at a drop-frame rate, in a fixed buffer.
struct TimecodeText {
  std::array<char, 12> chars{};
  std::string_view view() const { return {chars.data(), 11}; }
};
TimecodeText format_timecode(const Timecode& timecode, TimecodeRate rate);
TimecodeText format_frame(std::int64_t frame, TimecodeRate rate);

/// The frame number a moment falls in that comes `elapsed_ns` after the start of frame
/// `start` (before it when negative): start + floor(elapsed · fps), modulo frames_per_day.
/// |elapsed_ns| must stay below 24 hours.
std::int32_t frame_after(std::int64_t start, std::int64_t elapsed_ns, TimecodeRate rate);

/// Nanoseconds from the start of frame 0 to the start of frame `frame` (frame ≥ 0), rounded
/// down: frame / fps.
std::int64_t frame_start_ns(std::int64_t frame, TimecodeRate rate);

}  // namespace lipdrive
