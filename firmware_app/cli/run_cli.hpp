// What `lipdrive` and `lipdrive-dev` do around their subcommands: the log format, parsing,
// and turning a failure into a message and an exit code (command_error.hpp).
#pragma once

#include <string>

namespace CLI {
class App;
}

namespace lipdrive {

/// Logs to stderr as "level: message" under `name`, FFmpeg's messages too.
void set_up_logging(const std::string& name);

/// Parses the command line and runs the chosen subcommand. Returns the exit code: 0, the
/// code of a CommandError (after logging its message), CLI11's for a bad command line, 1 for
/// any other exception.
int run_cli(CLI::App& app, int argc, char** argv);

}  // namespace lipdrive
