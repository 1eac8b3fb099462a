#include "firmware_app/cli/out_option.hpp"

#include "firmware_app/cli/command_error.hpp"

#include <fmt/format.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace lipdrive {

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
