#include "firmware_app/tables/grid_align.hpp"

#include "firmware_app/cli/command_error.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>
#include <system_error>

namespace lipdrive {
namespace {

// An alignment covers one take: an hour is far beyond any, and keeps every frame number an
// int and the series eval builds over the words' frames small.
constexpr long kMaxAlignTime = 3600L * kAlignUnitsPerSecond;

std::optional<long> parse_time(const std::string& text) {
  long value = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (error != std::errc{} || end != text.data() + text.size() || value < 0 || value > kMaxAlignTime)
    return std::nullopt;
  return value;
}

std::optional<AlignedWord> parse_line(const std::string& line) {
  std::istringstream fields(line);
  std::string start, end, word, extra;
  if (!(fields >> start >> end >> word) || (fields >> extra)) return std::nullopt;
  const auto start_time = parse_time(start);
  const auto end_time = parse_time(end);
  if (!start_time || !end_time || *end_time <= *start_time) return std::nullopt;
  return AlignedWord{*start_time, *end_time, word};
}

}  // namespace

std::vector<AlignedWord> read_grid_align(const std::filesystem::path& path) {
  std::error_code error;
  std::ifstream in(path);
  if (!in || std::filesystem::is_directory(path, error)) {  // a folder opens, and reads as no words
    throw CommandError(fmt::format("cannot open alignment file {}", path.string()), kExitNoInput);
  }
  std::vector<AlignedWord> words;
  std::string line;
  for (int line_number = 1; std::getline(in, line); ++line_number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find_first_not_of(" \t") == std::string::npos) continue;
    auto word = parse_line(line);
    if (!word) {
      throw CommandError(fmt::format("{}:{}: expected 'start end word' with integer times "
                                     "0 <= start < end <= {} (an hour), got '{}'",
                                     path.string(), line_number, kMaxAlignTime, line),
                         kExitDataError);
    }
    // A transcript is one word after another: a word that starts before the last one ended
    // would be counted twice, and many of them would cost the closure metric their frames each.
    if (!words.empty() && word->start < words.back().end) {
      throw CommandError(fmt::format("{}:{}: '{}' starts at {}, before the word on the line above ends ({}): the "
                                     "words must follow one another",
                                     path.string(), line_number, line, word->start, words.back().end),
                         kExitDataError);
    }
    words.push_back(std::move(*word));
  }
  // Nothing to score against: an empty or blank transcript would report no closure, silently.
  if (words.empty()) throw CommandError(fmt::format("{}: no words", path.string()), kExitDataError);
  return words;
}

bool is_silence(const AlignedWord& word) { return word.word == "sil" || word.word == "sp"; }

FrameRange frame_range(const AlignedWord& word, double frames_per_second) {
  // Frame f spans [f, f + 1) / frames_per_second; end is exclusive, so the last frame holds
  // time end - 1.
  const auto frame_at = [frames_per_second](long time) {
    return static_cast<int>(std::floor(static_cast<double>(time) * frames_per_second / kAlignUnitsPerSecond));
  };
  return {frame_at(word.start), frame_at(word.end - 1)};
}

std::vector<FrameRange> speech_frames(std::span<const AlignedWord> words, double frames_per_second) {
  std::vector<FrameRange> ranges;
  for (const AlignedWord& word : words) {
    if (!is_silence(word)) ranges.push_back(frame_range(word, frames_per_second));
  }
  std::vector<FrameRange> merged;  // the words follow one another (read_grid_align): already in order
  for (const FrameRange& range : ranges) {
    if (!merged.empty() && range.first - 1 <= merged.back().last) {
      merged.back().last = std::max(merged.back().last, range.last);
    } else {
      merged.push_back(range);
    }
  }
  return merged;
}

bool contains(std::span<const FrameRange> ranges, int frame) {
  const auto after = std::upper_bound(ranges.begin(), ranges.end(), frame,
                                      [](int f, const FrameRange& range) { return f < range.first; });
  return after != ranges.begin() && std::prev(after)->last >= frame;
}

std::vector<WordFrames> word_frames(std::span<const AlignedWord> words, double frames_per_second) {
  std::vector<WordFrames> frames;
  frames.reserve(words.size());
  for (const AlignedWord& word : words) {
    const FrameRange range = frame_range(word, frames_per_second);
    frames.push_back({range.first, range.last, word.word, is_silence(word)});
  }
  return frames;
}

std::optional<FrameRange> word_frame_range(std::span<const AlignedWord> words, std::string_view word,
                                           double frames_per_second) {
  const auto it = std::find_if(words.begin(), words.end(), [word](const AlignedWord& w) { return w.word == word; });
  if (it == words.end()) return std::nullopt;
  return frame_range(*it, frames_per_second);
}

}  // namespace lipdrive
