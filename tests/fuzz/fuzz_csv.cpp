// CSV tables (`lipdrive eval --truth/--pred`, `plot`): read_csv_table and the numeric columns.
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const lipdrive::CsvTable table = lipdrive::read_csv_table(lipdrive::fuzz::input_file(data, size, ".csv"));
    for (const std::string& column : table.header) lipdrive::numeric_column(table, column);
  } catch (const lipdrive::CommandError&) {
  }
  return 0;
}
