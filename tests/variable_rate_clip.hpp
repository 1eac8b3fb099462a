// A variable-frame-rate clip made at test time, as a phone records one or as parts at different
// rates joined make one: a clip's frames given new times by FFmpeg, its first quarter a frame
// every 40 ms (25 fps), its middle half every 20 ms (50 fps), its last quarter every 40 ms again.
#pragma once

#include "command_run.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <filesystem>
#include <vector>

namespace lipdrive::test {

/// The times in seconds variable_rate_clip() gives `frames` frames, frame 0 at 0.
inline std::vector<double> variable_rate_times(int frames) {
  const int fast = frames / 4, slow = frames * 3 / 4;  // the 50 fps frames: [fast, slow)
  std::vector<double> times;
  for (int n = 0; n < frames; ++n)
    times.push_back((40 * std::min(n, fast) + 20 * std::clamp(n - fast, 0, slow - fast) + 40 * std::max(n - slow, 0)) /
                    1000.0);
  return times;
}

/// The first `frames` frames of `source` at variable_rate_times(), as MJPEG in `out` (its
/// container by its name: .mkv, .mp4), every frame kept at its time (timestamps in ms). FFmpeg's
/// exit code and messages.
inline CommandRun variable_rate_clip(const std::filesystem::path& source, int frames,
                                     const std::filesystem::path& out) {
  const int fast = frames / 4, slow = frames * 3 / 4;
  return run_command(fmt::format(
      "ffmpeg -v error -y -i {} -frames:v {} -an -vf \"settb=1/1000,setpts='40*min(N\\,{})+20*min(max(N-{}\\,0)\\,{})"
      "+40*max(N-{}\\,0)'\" -fps_mode passthrough -enc_time_base 1/1000 -c:v mjpeg -q:v 3 {}",
      source.string(), frames, fast, fast, slow - fast, slow, out.string()));
}

/// The presentation times of `clip`'s video frames as ffprobe reads them, in seconds.
inline std::vector<double> ffprobe_frame_times(const std::filesystem::path& clip) {
  const CommandRun run = run_command(
      fmt::format("ffprobe -v error -select_streams v -show_entries frame=pts_time -of csv=p=0 {}", clip.string()));
  std::vector<double> times;
  if (run.exit_code != 0) return times;
  for (std::size_t at = 0, end; (end = run.output.find('\n', at)) != std::string::npos; at = end + 1)
    if (end > at) times.push_back(std::stod(run.output.substr(at, end - at)));
  return times;
}

}  // namespace lipdrive::test
