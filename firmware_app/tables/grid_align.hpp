// GRID corpus word alignments (.align): one "start end word" line per word, times
// in 1/25000 s, so 1000 units are one frame of GRID's 25 fps video; "sil" and "sp" are
// silence. The words are placed on the frames of a recording at any rate.
#pragma once

#include "core/metrics.hpp"

#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

inline constexpr long kAlignUnitsPerSecond = 25000;
inline constexpr double kGridFramesPerSecond = 25;  // GRID's own video

struct AlignedWord {
  long start = 0;  // inclusive, align units
  long end = 0;    // exclusive, align units; end > start
  std::string word;
};

/// Inclusive range of video frames.
struct FrameRange {
  int first = 0;
  int last = 0;
};

/// Reads a .align file. Throws CommandError: kExitNoInput when it cannot be opened,
/// kExitDataError naming file and line for a malformed line (not three fields,
/// a time that is not a non-negative integer, end not after start, a start before the end of
/// the word above).
std::vector<AlignedWord> read_grid_align(const std::filesystem::path& path);

bool is_silence(const AlignedWord& word);

/// The frames, at `frames_per_second`, whose time span [f, f+1) / frames_per_second overlaps
/// the word's span, so a frame that is only partly inside the word still counts: the lips
/// move ahead of the sound, and an overlap rule never drops a short word.
FrameRange frame_range(const AlignedWord& word, double frames_per_second);

/// Frames overlapping any non-silence word, as ranges in order that neither overlap nor touch:
/// their cost is one per word, not one per frame.
std::vector<FrameRange> speech_frames(std::span<const AlignedWord> words, double frames_per_second);

/// Whether `frame` is in one of `ranges` (sorted, disjoint, as speech_frames gives them).
bool contains(std::span<const FrameRange> ranges, int frame);

/// The words as closure_metric (core/metrics.hpp) takes them; they refer to `words`' text.
std::vector<WordFrames> word_frames(std::span<const AlignedWord> words, double frames_per_second);

/// The frame range of the first occurrence of `word`, or nullopt when absent.
std::optional<FrameRange> word_frame_range(std::span<const AlignedWord> words, std::string_view word,
                                           double frames_per_second);

}  // namespace lipdrive
