// `lipdrive eval`: per-column agreement between a ground-truth CSV and an output
// CSV (docs/method.md 5), rows matched by frame number; with a GRID transcript
// (--align), also the closure metric of each output column (lips closing on the
// bilabial words, opening on the others, still in the final silence), the words placed
// by their times from the earliest row.
#include "core/metrics.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "firmware_app/tables/grid_align.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

// The mouth measures `lipdrive process` writes, in its column order.
constexpr std::array<std::string_view, 10> kMeasureColumns = {
    "width_2d",  "height_2d",     "width_fit", "height_fit", "width_3d",
    "height_3d", "protrusion_3d", "open",      "seal",       "protrusion_side"};
// Columns that identify or qualify a row rather than measure the mouth.
constexpr std::array<std::string_view, 5> kRowColumns = {"frame", "time_s", "source", "tracked", "quality"};

struct EvalOptions {
  std::string truth_path;
  std::string pred_path;
  std::vector<std::string> columns;
  std::string align_path;
  bool json = false;
};

struct ColumnAgreement {
  std::string column;
  SeriesAgreement agreement;
};

struct ColumnClosure {
  std::string column;
  ClosureMetric closure;
};

/// The measure columns both files have; failing that, every common column that is
/// not a row identifier, so two arbitrary tables can still be compared.
std::vector<std::string> default_columns(const CsvTable& truth, const CsvTable& pred) {
  std::vector<std::string> columns;
  for (std::string_view name : kMeasureColumns) {
    if (has_column(truth, name) && has_column(pred, name)) columns.emplace_back(name);
  }
  if (!columns.empty()) return columns;
  for (const std::string& name : truth.header) {
    const bool row_column = std::find(kRowColumns.begin(), kRowColumns.end(), name) != kRowColumns.end();
    if (!row_column && has_column(pred, name)) columns.push_back(name);
  }
  if (columns.empty()) {
    throw CommandError(
        fmt::format("{} and {} have no measure column in common", truth.path.string(), pred.path.string()),
        kExitDataError);
  }
  return columns;
}

/// Frame number of each row; throws naming file and line for a missing,
/// non-integer or repeated frame number.
std::vector<int> frame_numbers(const CsvTable& table) {
  const std::vector<double> values = numeric_column(table, "frame");
  std::vector<int> frames;
  std::set<int> seen;
  for (std::size_t row = 0; row < values.size(); ++row) {
    const double value = values[row];
    const auto where = fmt::format("{}:{}", table.path.string(), table.line_numbers[row]);
    if (!(value >= 0) || value != std::floor(value) || value > 1e9) {
      throw CommandError(where + ": frame must be a non-negative integer", kExitDataError);
    }
    if (!seen.insert(static_cast<int>(value)).second) {
      throw CommandError(fmt::format("{}: frame {} appears twice", where, value), kExitDataError);
    }
    frames.push_back(static_cast<int>(value));
  }
  return frames;
}

/// The table's frames per second from its frame and time_s columns (first and last rows, to a
/// thousandth: time_s is written to 0.1 ms); GRID's 25 without a time_s column or a second
/// time. Throws naming the file for a rate outside 1..1000, and for a row whose time lies more
/// than a frame from where that rate puts its frame (a variable-frame-rate recording, a camera
/// that slowed down): words placed by frame at one rate would fall on the wrong frames there.
double frames_per_second(const CsvTable& table) {
  if (!has_column(table, "time_s")) return kGridFramesPerSecond;
  const std::vector<int> frames = frame_numbers(table);
  const std::vector<double> times = numeric_column(table, "time_s");
  if (frames.size() < 2) return kGridFramesPerSecond;
  // A clock that stands still or runs back gives no rate (it was taken for GRID's 25 frames/s).
  if (!(times.back() > times.front()))
    throw CommandError(fmt::format("{}: time_s of the last row ({}) is not after the first row's ({}): the table "
                                   "gives no frame rate to place the words at",
                                   table.path.string(), times.back(), times.front()),
                       kExitDataError);
  const double rate = std::round(1000.0 * (frames.back() - frames.front()) / (times.back() - times.front())) / 1000;
  if (!(rate >= 1 && rate <= 1000)) {
    throw CommandError(
        fmt::format("{}: its frame and time_s columns give {:.3g} frames per second (1 to 1000 expected)",
                    table.path.string(), rate),
        kExitDataError);
  }
  for (std::size_t row = 0; row < frames.size(); ++row) {
    const double expected_s = times.front() + (frames[row] - frames.front()) / rate;
    if (!(std::abs(times[row] - expected_s) <= 1 / rate)) {
      throw CommandError(
          fmt::format("{}: frame {} is at {:.4f} s, {:.4f} s from where the first and last rows' {:.3g} frames per "
                      "second put it: its frames are not at one rate (a variable-frame-rate recording?), so the "
                      "words cannot be placed on them",
                      table.path.string(), frames[row], times[row], times[row] - expected_s, rate),
          kExitDataError);
    }
  }
  return rate;
}

/// Row indices (truth, pred) of the frames present in both tables, in truth order;
/// restricted to `scored_frames` when given.
std::vector<std::pair<std::size_t, std::size_t>> matched_rows(
    const CsvTable& truth, const CsvTable& pred, const std::optional<std::vector<FrameRange>>& scored_frames) {
  std::map<int, std::size_t> pred_row_of_frame;
  const std::vector<int> pred_frames = frame_numbers(pred);
  for (std::size_t row = 0; row < pred_frames.size(); ++row) pred_row_of_frame[pred_frames[row]] = row;

  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  const std::vector<int> truth_frames = frame_numbers(truth);
  for (std::size_t row = 0; row < truth_frames.size(); ++row) {
    const int frame = truth_frames[row];
    if (scored_frames && !contains(*scored_frames, frame)) continue;
    if (const auto it = pred_row_of_frame.find(frame); it != pred_row_of_frame.end()) {
      pairs.emplace_back(row, it->second);
    }
  }
  return pairs;
}

std::vector<ColumnAgreement> compare_columns(const CsvTable& truth, const CsvTable& pred,
                                             const std::vector<std::string>& columns,
                                             const std::vector<std::pair<std::size_t, std::size_t>>& rows) {
  std::vector<ColumnAgreement> results;
  for (const std::string& column : columns) {
    const std::vector<double> truth_values = numeric_column(truth, column);
    const std::vector<double> pred_values = numeric_column(pred, column);
    std::vector<double> z, z_hat;
    for (const auto& [truth_row, pred_row] : rows) {
      z.push_back(truth_values[truth_row]);
      z_hat.push_back(pred_values[pred_row]);
    }
    results.push_back({column, compare_series(z, z_hat)});
  }
  return results;
}

/// The measure columns of an output scored on its own (closure metric without truth).
std::vector<std::string> output_columns(const CsvTable& pred) {
  std::vector<std::string> columns;
  for (std::string_view name : kMeasureColumns)
    if (has_column(pred, name)) columns.emplace_back(name);
  if (columns.empty())
    throw CommandError(fmt::format("{} has no mouth measure column", pred.path.string()), kExitDataError);
  return columns;
}

/// The frame number the transcript's time 0 falls on: the earliest row's (a take's frame is
/// its capture sequence number, which need not start at 0).
int first_frame(const CsvTable& table) {
  const std::vector<int> frames = frame_numbers(table);
  return frames.empty() ? 0 : *std::min_element(frames.begin(), frames.end());
}

/// closure_metric of each column, its values placed by frame number from `origin` (NaN where a
/// frame is missing or was not tracked); `words` are on the frames from `origin`, and the
/// results' words are given back on the CSV's frame numbers. Rows past the words and their
/// closure windows count only toward the range the values are scaled by, so the series ends
/// there: a frame number far out (a take's after a long outage, a damaged row) costs no memory.
std::vector<ColumnClosure> closure_columns(const CsvTable& pred, const std::vector<std::string>& columns,
                                           std::span<const WordFrames> words, double frames_per_second, int origin) {
  const std::vector<int> frames = frame_numbers(pred);
  int words_end = 0;
  for (const WordFrames& w : words) words_end = std::max(words_end, w.last);
  words_end += static_cast<int>(std::lround(ClosureMetric::kWidening_s * frames_per_second));
  const int count =
      frames.empty() ? 0 : std::min(*std::max_element(frames.begin(), frames.end()) - origin, words_end) + 1;
  std::vector<ColumnClosure> results;
  for (const std::string& column : columns) {
    const std::vector<double> values = numeric_column(pred, column);
    std::vector<double> series(static_cast<std::size_t>(count), std::nan(""));
    for (std::size_t row = 0; row < frames.size(); ++row)
      if (frames[row] - origin < count) series[static_cast<std::size_t>(frames[row] - origin)] = values[row];
    ClosureMetric metric = closure_metric(series, words, frames_per_second, values);
    for (WordClosure& w : metric.words) w.first += origin, w.last += origin;
    results.push_back({column, std::move(metric)});
  }
  return results;
}

void print_table(const std::vector<ColumnAgreement>& results) {
  std::size_t name_width = std::string_view("column").size();
  for (const auto& result : results) name_width = std::max(name_width, result.column.size());
  fmt::print("{:<{}} {:>6} {:>12} {:>12} {:>12} {:>10} {:>10}\n", "column", name_width, "n", "rmse_scaled", "mae",
             "max_abs", "pearson_r", "std_ratio");
  for (const auto& [column, a] : results) {
    fmt::print("{:<{}} {:>6} {:>12.4f} {:>12.5g} {:>12.5g} {:>10.4f} {:>10.4f}\n", column, name_width, a.pairs_used,
               a.rmse_scaled, a.mae, a.max_abs_error, a.pearson_r, a.std_ratio);
  }
}

void print_closures(const std::vector<ColumnClosure>& results) {
  std::size_t name_width = std::string_view("column").size();
  for (const auto& result : results) name_width = std::max(name_width, result.column.size());
  fmt::print("closure metric (min-max scaled; a closure is <= {:.1f} within {:.0f} ms of a bilabial word):\n",
             ClosureMetric::kClosureLevel, 1000 * ClosureMetric::kWidening_s);
  fmt::print("{:<{}} {:>10} {:>8} {:>15} {:>15}\n", "column", name_width, "closures", "opening", "silence_median",
             "silence_jitter");
  for (const auto& [column, m] : results) {
    fmt::print("{:<{}} {:>10} {:>8.3f} {:>15.3f} {:>15.4f}\n", column, name_width,
               fmt::format("{}/{}", m.closures_seen, m.bilabial_words), m.opening, m.silence_median, m.silence_jitter);
    for (const WordClosure& w : m.words)
      if (w.outside)
        fmt::print("  {}: \"{}\" (frames {}..{}) outside the rows: not scored\n", column, w.word, w.first, w.last);
      else if (std::isnan(w.minimum))
        fmt::print("  {}: \"{}\" (frames {}..{}) not closed: no frame of it tracked\n", column, w.word, w.first,
                   w.last);
      else if (!w.closed)
        fmt::print("  {}: \"{}\" (frames {}..{}) not closed: minimum {:.3f}\n", column, w.word, w.first, w.last,
                   w.minimum);
  }
}

/// NaN becomes JSON null.
nlohmann::json number(double value) { return std::isnan(value) ? nlohmann::json() : nlohmann::json(value); }

nlohmann::json closures_json(const std::vector<ColumnClosure>& results) {
  nlohmann::json json = nlohmann::json::array();
  for (const auto& [column, m] : results) {
    nlohmann::json words = nlohmann::json::array();
    for (const WordClosure& w : m.words)
      words.push_back({{"word", w.word},
                       {"first", w.first},
                       {"last", w.last},
                       {"minimum", number(w.minimum)},
                       {"closed", w.closed},
                       {"outside", w.outside}});
    json.push_back({{"column", column},
                    {"bilabial_words", m.bilabial_words},
                    {"closures_seen", m.closures_seen},
                    {"opening", number(m.opening)},
                    {"silence_median", number(m.silence_median)},
                    {"silence_jitter", number(m.silence_jitter)},
                    {"words", words}});
  }
  return json;
}

/// Undefined metrics (NaN) become JSON null.
nlohmann::json to_json(const EvalOptions& options, std::size_t frames_matched,
                       const std::vector<ColumnAgreement>& results, const std::vector<ColumnClosure>& closures) {
  nlohmann::json json;
  json["truth"] = options.truth_path.empty() ? nlohmann::json() : nlohmann::json(options.truth_path);
  json["pred"] = options.pred_path;
  json["align"] = options.align_path.empty() ? nlohmann::json() : nlohmann::json(options.align_path);
  json["frames_matched"] = frames_matched;
  json["columns"] = nlohmann::json::array();
  for (const auto& [column, a] : results) {
    json["columns"].push_back({{"column", column},
                               {"n", a.pairs_used},
                               {"rmse_scaled", a.rmse_scaled},
                               {"mae", a.mae},
                               {"max_abs", a.max_abs_error},
                               {"pearson_r", a.pearson_r},
                               {"std_ratio", a.std_ratio}});
  }
  if (!options.align_path.empty()) json["closure"] = closures_json(closures);
  return json;
}

void run_eval(const EvalOptions& options) {
  if (options.truth_path.empty() && options.align_path.empty()) throw CLI::RequiredError("--truth or --align");
  const CsvTable pred = read_csv_table(options.pred_path);
  std::vector<AlignedWord> align;
  if (!options.align_path.empty()) align = read_grid_align(options.align_path);
  const double rate = align.empty() ? kGridFramesPerSecond : frames_per_second(pred);  // the words' frames
  // The words' frames count from the earliest row of the files (the truth shares the output's
  // frame numbers).
  int origin = first_frame(pred);

  std::vector<ColumnAgreement> results;
  std::size_t frames_matched = 0;
  std::vector<std::string> columns = options.columns;
  if (!options.truth_path.empty()) {
    const CsvTable truth = read_csv_table(options.truth_path);
    if (columns.empty()) columns = default_columns(truth, pred);
    origin = std::min(origin, first_frame(truth));
    std::optional<std::vector<FrameRange>> scored_frames;
    if (!align.empty()) {
      scored_frames = speech_frames(align, rate);
      for (FrameRange& range : *scored_frames) range.first += origin, range.last += origin;
    }
    const auto rows = matched_rows(truth, pred, scored_frames);
    if (rows.empty()) {
      throw CommandError(fmt::format("{} and {} have no {}frames in common", options.truth_path, options.pred_path,
                                     scored_frames ? "speech " : ""),
                         kExitDataError);
    }
    frames_matched = rows.size();
    results = compare_columns(truth, pred, columns, rows);
  } else if (columns.empty()) {
    columns = output_columns(pred);
  }
  std::vector<ColumnClosure> closures;
  if (!align.empty()) closures = closure_columns(pred, columns, word_frames(align, rate), rate, origin);

  if (options.json) {
    std::cout << to_json(options, frames_matched, results, closures).dump(2) << '\n';
    return;
  }
  if (!options.truth_path.empty()) {
    fmt::print("truth {} vs output {}: {} {}frames matched\n", options.truth_path, options.pred_path, frames_matched,
               align.empty() ? "" : "speech ");
    print_table(results);
  }
  if (!align.empty()) {
    fmt::print("output {} against the words of {} at {:g} frames/s\n", options.pred_path, options.align_path, rate);
    print_closures(closures);
  }
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto options = std::make_shared<EvalOptions>();
  CLI::App* eval =
      app.add_subcommand("eval",
                         "Compare an output CSV with ground truth: scaled RMSE, MAE, max error, Pearson r, "
                         "std ratio per column; with --align, the lip-closure metric");
  eval->add_option("--truth", options->truth_path, "Ground-truth CSV (or any per-frame CSV); optional with --align");
  eval->add_option("--pred", options->pred_path, "Output CSV to score, e.g. from lipdrive process")->required();
  eval->add_option("--columns", options->columns, "Columns to compare (default: the mouth measures both files have)")
      ->delimiter(',');
  eval->add_option("--align", options->align_path,
                   "GRID .align transcript: score only frames overlapping spoken words, and report the closure "
                   "metric of each output column (bilabial closures seen, opening, final-silence median and jitter)");
  eval->add_flag("--json", options->json, "Print JSON instead of a table");
  eval->callback([options] { run_eval(*options); });
}

}  // namespace lipdrive
