// The project's CSV reader: the per-frame files `lipdrive process` writes and the
// ground-truth files of the fixture generator. Comma-separated, header first;
// a field may be double-quoted ("" inside quotes is a quote). Every error is a
// CommandError naming the file, and the line and column where there is one.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace lipdrive {

/// Hashes a std::string and a std::string_view alike, so a column is looked up by a view.
struct ColumnNameHash {
  using is_transparent = void;
  std::size_t operator()(std::string_view name) const { return std::hash<std::string_view>{}(name); }
};

struct CsvTable {
  std::filesystem::path path;                  // for error messages
  std::vector<std::string> header;             // column names in file order
  std::vector<std::vector<std::string>> rows;  // each has header.size() fields
  std::vector<int> line_numbers;               // 1-based file line of each row
  // Each column name's index in `header`: a lookup costs the same however many columns there are.
  std::unordered_map<std::string, std::size_t, ColumnNameHash, std::equal_to<>> column_of;
};

/// Reads a whole CSV file; blank lines, and lines starting with '#' before the header, are
/// skipped. Throws CommandError:
/// kExitNoInput when the file cannot be opened, kExitDataError for an empty file,
/// duplicate column names, an unterminated quote or a row with the wrong field count.
CsvTable read_csv_table(const std::filesystem::path& path);

bool has_column(const CsvTable& table, std::string_view name);

/// Index of a column; throws CommandError (kExitDataError) naming the file and column.
std::size_t column_index(const CsvTable& table, std::string_view name);

/// A column as numbers, one per row: an empty field (e.g. a measure on an untracked
/// frame) is NaN. Throws CommandError naming file, line and column for a field that
/// is not a number or is infinite, or when the column is missing.
std::vector<double> numeric_column(const CsvTable& table, std::string_view name);

}  // namespace lipdrive
