// FFmpeg's own messages (a damaged packet, a file without its index, a decoder concealing
// errors) through spdlog, as every other message of lipdrive, instead of FFmpeg's default of
// printing them to stderr in its own format.
#pragma once

#include <string>

namespace lipdrive {

/// From now on FFmpeg's errors and warnings are logged as warnings, "ffmpeg: mpegts: Packet
/// corrupt ...", its information as debug messages, the rest dropped. Call once, before FFmpeg
/// is used; its threads may log at any time after.
void route_ffmpeg_log();

/// FFmpeg's last error line on this thread since the call before, "yuv4mpegpipe: ..."; empty
/// when there was none (or the log is not routed). The reason behind a failure whose return
/// code says little (a y4m header of 30000×30000 pixels fails as "Device or resource busy").
std::string take_ffmpeg_error();

}  // namespace lipdrive
