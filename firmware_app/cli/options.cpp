#include "firmware_app/cli/options.hpp"

#include "firmware_app/cli/command_error.hpp"

#include <fmt/format.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace lipdrive {

CLI::Validator finite_range(double min, double max) {
  return CLI::Validator(
      [min, max](std::string& text) {
        double value = 0;
        if (CLI::detail::lexical_cast(text, value) && value >= min && value <= max) return std::string();
        return fmt::format("{} is not a number in [{}, {}]", text, min, max);
      },
      fmt::format("NUMBER in [{} - {}]", min, max));
}

void refuse_out_over_input(const CLI::App& command) {
  namespace fs = std::filesystem;
  const CLI::Option* out = command.get_option_no_throw("--out");
  if (out == nullptr || out->count() == 0) return;
  const fs::path target = out->as<std::string>();
  std::error_code error;
  if (!fs::is_regular_file(target, error)) return;  // a new file, or a stream ("-"): nothing read is at stake
  for (const CLI::Option* option : command.get_options()) {
    if (option == out) continue;
    for (const std::string& value : option->results())
      if (fs::equivalent(value, target, error))
        throw CommandError(fmt::format("--out {}: the file is also {} ({}); writing it would replace what the "
                                       "command reads, so nothing was written",
                                       target.string(), option->get_name(), value),
                           kExitUsage);
  }
}

}  // namespace lipdrive
