#include "firmware_app/tables/measures_csv.hpp"

#include <cmath>
#include <iterator>

namespace lipdrive {
namespace {

std::string csv_field(std::string_view text) {
  if (text.find_first_of(",\"\r\n") == std::string_view::npos) return std::string(text);
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + '"';
}

/// ",value" with `decimals` places; "," alone where the value is not finite: a measure the
/// frame could not give is missing, as an untracked frame's are, and the table's readers refuse
/// nan and inf.
void append_value(fmt::memory_buffer& row, double value, int decimals) {
  if (std::isfinite(value))
    fmt::format_to(std::back_inserter(row), ",{:.{}f}", value, decimals);
  else
    row.push_back(',');
}

}  // namespace

std::string measures_csv_header(bool include_landmarks) {
  std::string header =
      "frame,time_s,source,tracked,quality,width_2d,height_2d,width_fit,height_fit,width_3d,height_3d,protrusion_3d,"
      "open,seal";
  for (int v = 0; v < kNumVisemes; ++v) header += fmt::format(",{}", signal_name(viseme_signal(v)));
  for (int a = 0; a < kNumArkit; ++a) header += fmt::format(",{}", signal_name(arkit_signal(a)));
  if (include_landmarks) {
    for (int i = 0; i < kNumLandmarks; ++i) header += fmt::format(",x{}", i);
    for (int i = 0; i < kNumLandmarks; ++i) header += fmt::format(",y{}", i);
  }
  return header;
}

void append_measures_csv_row(fmt::memory_buffer& row, const CsvRowKey& key, const MouthMeasures* measures,
                             std::span<const float, kNumVisemes> visemes, std::span<const float, kNumArkit> arkit,
                             const Landmarks2D* landmarks) {
  fmt::format_to(std::back_inserter(row), "{},{:.4f},{},", key.frame, key.time_s, csv_field(key.source));
  if (measures) {
    const MouthMeasures& m = *measures;
    row.push_back('1');
    append_value(row, m.quality, 4);
    for (const double value :
         {m.width_2d, m.height_2d, m.width_fit, m.height_fit, m.width_3d, m.height_3d, m.protrusion_3d, m.open})
      append_value(row, value, 6);
    append_value(row, m.seal, 4);
    for (const float weight : visemes) append_value(row, weight, 4);
    for (const float weight : arkit) append_value(row, weight, 4);
  } else {
    fmt::format_to(std::back_inserter(row), "0,,,,,,,,,,");
    for (int column = 0; column < kNumVisemes + kNumArkit; ++column) row.push_back(',');
  }
  if (!landmarks) return;
  for (int axis = 0; axis < 2; ++axis)
    for (int i = 0; i < kNumLandmarks; ++i) {
      append_value(row, measures ? (*landmarks)(axis, i) : std::nan(""), 3);
    }
}

}  // namespace lipdrive
