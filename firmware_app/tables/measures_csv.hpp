// The measures CSV: the per-frame table `lipdrive process` writes and the daemon's take
// recorder appends to (the same columns), and tables/csv_table.hpp reads back.
#pragma once

#include "core/drive_signals.hpp"
#include "core/landmarks.hpp"
#include "core/mouth_measures.hpp"
#include "core/timecode.hpp"

#include <fmt/format.h>

#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace lipdrive {

/// Where a CSV row's frame came from.
struct CsvRowKey {
  std::uint64_t frame = 0;
  double time_s = 0;
  std::string_view source;
};

/// The column names, without the line end: the measures, then viseme_Aah..viseme_W, then the
/// 52 ARKit weights arkit_eyeBlinkLeft..arkit_tongueOut (core/arkit.hpp); with
/// `include_landmarks`, x0..x67,y0..y67 follow.
std::string measures_csv_header(bool include_landmarks);

/// One row under measures_csv_header, without the line end. `measures` null: the frame was
/// not tracked (empty fields; `visemes` and `arkit` are not read). `landmarks` null: no
/// landmark columns.
void append_measures_csv_row(fmt::memory_buffer& row, const CsvRowKey& key, const MouthMeasures* measures,
                             std::span<const float, kNumVisemes> visemes, std::span<const float, kNumArkit> arkit,
                             const Landmarks2D* landmarks);

/// "HH:MM:SS:FF" (';' before the frames at 29.97 drop-frame) of a frame number: the timecode
/// column of takes and of `lipdrive process --timecode`.
inline void append_timecode(fmt::memory_buffer& row, std::int32_t frame, TimecodeRate rate) {
  const TimecodeText text = format_frame(frame, rate);
  row.append(text.view());
}

}  // namespace lipdrive
