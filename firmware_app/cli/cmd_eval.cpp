// `lipdrive eval`: per-column agreement between a ground-truth CSV and an output
// CSV (docs/method.md 5), rows matched by frame number.
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
constexpr std::array<std::string_view, 8> kMeasureColumns = {
    "width_2d", "height_2d", "width_fit", "height_fit", "width_3d", "height_3d", "protrusion_3d", "protrusion_side"};
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

/// Row indices (truth, pred) of the frames present in both tables, in truth order;
/// restricted to `scored_frames` when given.
std::vector<std::pair<std::size_t, std::size_t>> matched_rows(const CsvTable& truth, const CsvTable& pred,
                                                              const std::optional<std::set<int>>& scored_frames) {
  std::map<int, std::size_t> pred_row_of_frame;
  const std::vector<int> pred_frames = frame_numbers(pred);
  for (std::size_t row = 0; row < pred_frames.size(); ++row) pred_row_of_frame[pred_frames[row]] = row;

  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  const std::vector<int> truth_frames = frame_numbers(truth);
  for (std::size_t row = 0; row < truth_frames.size(); ++row) {
    const int frame = truth_frames[row];
    if (scored_frames && !scored_frames->contains(frame)) continue;
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

/// Undefined metrics (NaN) become JSON null.
nlohmann::json to_json(const EvalOptions& options, std::size_t frames_matched,
                       const std::vector<ColumnAgreement>& results) {
  nlohmann::json json;
  json["truth"] = options.truth_path;
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
  return json;
}

void run_eval(const EvalOptions& options) {
  const CsvTable truth = read_csv_table(options.truth_path);
  const CsvTable pred = read_csv_table(options.pred_path);
  const std::vector<std::string> columns = options.columns.empty() ? default_columns(truth, pred) : options.columns;

  std::optional<std::set<int>> scored_frames;
  if (!options.align_path.empty()) scored_frames = speech_frames(read_grid_align(options.align_path));
  const auto rows = matched_rows(truth, pred, scored_frames);
  if (rows.empty()) {
    throw CommandError(fmt::format("{} and {} have no {}frames in common", options.truth_path, options.pred_path,
                                   scored_frames ? "speech " : ""),
                       kExitDataError);
  }

  const std::vector<ColumnAgreement> results = compare_columns(truth, pred, columns, rows);
  if (options.json) {
    std::cout << to_json(options, rows.size(), results).dump(2) << '\n';
    return;
  }
  fmt::print("truth {} vs output {}: {} {}frames matched\n", options.truth_path, options.pred_path, rows.size(),
             scored_frames ? "speech " : "");
  print_table(results);
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto options = std::make_shared<EvalOptions>();
  CLI::App* eval =
      app.add_subcommand("eval",
                         "Compare an output CSV with ground truth: scaled RMSE, MAE, max error, Pearson r, "
                         "std ratio per column");
  eval->add_option("--truth", options->truth_path, "Ground-truth CSV (or any per-frame CSV)")->required();
  eval->add_option("--pred", options->pred_path, "Output CSV to score, e.g. from lipdrive process")->required();
  eval->add_option("--columns", options->columns, "Columns to compare (default: the mouth measures both files have)")
      ->delimiter(',');
  eval->add_option("--align", options->align_path,
                   "GRID .align transcript: score only frames overlapping spoken words");
  eval->add_flag("--json", options->json, "Print JSON instead of a table");
  eval->callback([options] { run_eval(*options); });
}

}  // namespace lipdrive
