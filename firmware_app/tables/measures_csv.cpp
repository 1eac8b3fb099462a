#include "firmware_app/tables/measures_csv.hpp"

#include <iterator>

namespace lipdrive {
namespace {

std::string csv_field(std::string_view text) {
  if (text.find_first_of(",\"\r\n") == std::string_view::npos) return std::string(text);
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + '"';
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
    fmt::format_to(std::back_inserter(row), "1,{:.4f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.4f}",
                   m.quality, m.width_2d, m.height_2d, m.width_fit, m.height_fit, m.width_3d, m.height_3d,
                   m.protrusion_3d, m.open, m.seal);
    for (const float weight : visemes) fmt::format_to(std::back_inserter(row), ",{:.4f}", weight);
    for (const float weight : arkit) fmt::format_to(std::back_inserter(row), ",{:.4f}", weight);
  } else {
    fmt::format_to(std::back_inserter(row), "0,,,,,,,,,,");
    for (int column = 0; column < kNumVisemes + kNumArkit; ++column) row.push_back(',');
  }
  if (!landmarks) return;
  for (int axis = 0; axis < 2; ++axis)
    for (int i = 0; i < kNumLandmarks; ++i) {
      if (measures)
        fmt::format_to(std::back_inserter(row), ",{:.3f}", (*landmarks)(axis, i));
      else
        row.push_back(',');
    }
}

}  // namespace lipdrive
