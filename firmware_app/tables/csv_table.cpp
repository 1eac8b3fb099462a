#include "firmware_app/tables/csv_table.hpp"

#include "firmware_app/cli/command_error.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <limits>
#include <optional>
#include <system_error>

namespace lipdrive {
namespace {

std::string_view trimmed(std::string_view text) {
  const auto first = text.find_first_not_of(" \t");
  if (first == std::string_view::npos) return {};
  const auto last = text.find_last_not_of(" \t");
  return text.substr(first, last - first + 1);
}

/// Splits one line into fields; a quoted field keeps its commas, and "" inside it
/// is a literal quote. Returns nullopt for an unterminated quote.
std::optional<std::vector<std::string>> split_fields(std::string_view line) {
  std::vector<std::string> fields;
  std::string field;
  bool in_quotes = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (in_quotes) {
      if (c != '"') {
        field += c;
      } else if (i + 1 < line.size() && line[i + 1] == '"') {
        field += '"';
        ++i;
      } else {
        in_quotes = false;
      }
    } else if (c == '"') {
      in_quotes = true;
    } else if (c == ',') {
      fields.emplace_back(trimmed(field));
      field.clear();
    } else {
      field += c;
    }
  }
  if (in_quotes) return std::nullopt;
  fields.emplace_back(trimmed(field));
  return fields;
}

[[noreturn]] void data_error(const CsvTable& table, int line, const std::string& problem) {
  throw CommandError(fmt::format("{}:{}: {}", table.path.string(), line, problem), kExitDataError);
}

}  // namespace

CsvTable read_csv_table(const std::filesystem::path& path) {
  std::error_code error;
  if (std::filesystem::is_directory(path, error))  // a folder opens, then fails to read
    throw CommandError(fmt::format("{}: a folder, not a CSV table", path.string()), kExitNoInput);
  std::ifstream in(path);
  if (!in) throw CommandError(fmt::format("cannot open CSV file {}", path.string()), kExitNoInput);

  CsvTable table{path, {}, {}, {}};
  std::string line;
  for (int line_number = 1; std::getline(in, line); ++line_number) {
    if (!line.empty() && line.back() == '\r') line.pop_back();  // CRLF files
    if (trimmed(line).empty()) continue;
    // Comment lines before the header (a take's timecode_start).
    if (table.header.empty() && line.front() == '#') continue;
    auto fields = split_fields(line);
    if (!fields) data_error(table, line_number, "unterminated quoted field");
    if (table.header.empty()) {
      table.header = std::move(*fields);
      for (std::size_t i = 0; i < table.header.size(); ++i) {
        if (!table.column_of.emplace(table.header[i], i).second) {
          data_error(table, line_number, fmt::format("duplicate column '{}'", table.header[i]));
        }
      }
      continue;
    }
    if (fields->size() != table.header.size()) {
      data_error(table, line_number,
                 fmt::format("expected {} fields as in the header, found {}", table.header.size(), fields->size()));
    }
    table.rows.push_back(std::move(*fields));
    table.line_numbers.push_back(line_number);
  }
  if (in.bad()) throw CommandError(fmt::format("error reading {}", path.string()), kExitNoInput);
  if (table.header.empty()) {
    throw CommandError(fmt::format("{}: empty CSV file, expected a header line", path.string()), kExitDataError);
  }
  return table;
}

bool has_column(const CsvTable& table, std::string_view name) { return table.column_of.contains(name); }

std::size_t column_index(const CsvTable& table, std::string_view name) {
  const auto it = table.column_of.find(name);
  if (it == table.column_of.end()) {
    throw CommandError(fmt::format("{}: no column '{}'", table.path.string(), name), kExitDataError);
  }
  return it->second;
}

std::vector<double> numeric_column(const CsvTable& table, std::string_view name) {
  const std::size_t column = column_index(table, name);
  std::vector<double> values;
  values.reserve(table.rows.size());
  for (std::size_t row = 0; row < table.rows.size(); ++row) {
    const std::string& field = table.rows[row][column];
    if (field.empty()) {
      values.push_back(std::numeric_limits<double>::quiet_NaN());
      continue;
    }
    double value = 0;
    const auto [end, error] = std::from_chars(field.data(), field.data() + field.size(), value);
    if (error != std::errc{} || end != field.data() + field.size()) {
      data_error(table, table.line_numbers[row], fmt::format("column '{}': '{}' is not a number", name, field));
    }
    // No measure is infinite or nan; a missing or untracked value is an empty field (as
    // `process` and the takes write it), so a nan is not a missing value but a broken one.
    if (!std::isfinite(value)) {
      data_error(table, table.line_numbers[row], fmt::format("column '{}': '{}' is not a finite number", name, field));
    }
    values.push_back(value);
  }
  return values;
}

}  // namespace lipdrive
