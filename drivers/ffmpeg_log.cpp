#include "drivers/ffmpeg_log.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

extern "C" {
#include <libavutil/log.h>
}

#include <algorithm>
#include <array>
#include <cstdarg>
#include <cstdio>
#include <string_view>
#include <utility>

namespace lipdrive {
namespace {

thread_local std::string last_error;  // this thread's, for take_ffmpeg_error()

/// FFmpeg's log callback: one spdlog line per line of FFmpeg's, named by the component that
/// sent it (its AVClass item name: the demuxer, the decoder) rather than by its address. FFmpeg
/// writes some lines in pieces ("Packet corrupt (...)", then ".\n"): the pieces are gathered
/// per thread until the newline.
void log_message(void* component, int level, const char* format, va_list args) {
  if (level > AV_LOG_INFO) return;
  thread_local std::array<char, 1024> line{};
  thread_local std::size_t used = 0;
  const int written = std::vsnprintf(line.data() + used, line.size() - used, format, args);
  if (written < 0) return;
  used = std::min(used + static_cast<std::size_t>(written), line.size() - 1);
  std::string_view message(line.data(), used);
  if (!message.ends_with('\n') && used < line.size() - 1) return;  // the rest of the line follows
  used = 0;
  while (!message.empty() && (message.back() == '\n' || message.back() == '\r')) message.remove_suffix(1);
  if (message.empty()) return;
  const AVClass* kind = component != nullptr ? *static_cast<const AVClass* const*>(component) : nullptr;
  const char* name = kind != nullptr && kind->item_name != nullptr ? kind->item_name(component) : nullptr;
  std::array<char, 1200> text{};
  const auto end = fmt::format_to_n(text.data(), text.size(), "{}{}{}", name != nullptr ? name : "",
                                    name != nullptr ? ": " : "", message);
  const std::string_view whole(text.data(), std::min(end.size, text.size()));
  if (level <= AV_LOG_ERROR) last_error = whole;
  // A line that repeats this thread's last one (a damaged stream says the same thing every
  // frame) is counted, and the count logged before the thread's next different line.
  thread_local std::array<char, 1200> last{};
  thread_local std::size_t last_size = 0, repeats = 0;
  const std::string_view previous(last.data(), last_size);
  if (whole == previous) {
    ++repeats;
    return;
  }
  if (repeats > 0) spdlog::warn("ffmpeg: {} ({} more times)", previous, repeats);
  repeats = 0;
  last_size = whole.copy(last.data(), last.size());
  if (level <= AV_LOG_WARNING)
    spdlog::warn("ffmpeg: {}", whole);
  else
    spdlog::debug("ffmpeg: {}", whole);
}

}  // namespace

void route_ffmpeg_log() { av_log_set_callback(log_message); }

std::string take_ffmpeg_error() { return std::exchange(last_error, {}); }

}  // namespace lipdrive
