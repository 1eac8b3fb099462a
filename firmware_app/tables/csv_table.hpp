// The project's CSV reader: the per-frame files `lipdrive process` writes and the
// ground-truth files of the fixture generator. Comma-separated, header first;
// a field may be double-quoted ("" inside quotes is a quote). Every error is a
// CommandError naming the file, and the line and column where there is one.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace lipdrive {

struct CsvTable {
  std::filesystem::path path;                  // for error messages
  std::vector<std::string> header;             // column names in file order
  std::vector<std::vector<std::string>> rows;  // each has header.size() fields
  std::vector<int> line_numbers;               // 1-based file line of each row
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
/// is not a number, or when the column is missing.
std::vector<double> numeric_column(const CsvTable& table, std::string_view name);

}  // namespace lipdrive
