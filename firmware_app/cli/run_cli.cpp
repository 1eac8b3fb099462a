#include "firmware_app/cli/run_cli.hpp"

#include "drivers/ffmpeg_log.hpp"
#include "firmware_app/cli/command_error.hpp"

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <exception>

namespace lipdrive {

void set_up_logging(const std::string& name) {
  spdlog::set_default_logger(spdlog::stderr_color_mt(name));
  spdlog::set_pattern("%^%l%$: %v");
  route_ffmpeg_log();
}

int run_cli(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the message or the help; its own codes (105, 106, ...) mean nothing to a
    // script or a unit file, so every mistake on the command line is EX_USAGE.
    return app.exit(e) == 0 ? 0 : kExitUsage;
  } catch (const CommandError& e) {
    spdlog::error("{}", e.what());
    return e.exit_code();
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return kExitFailure;
  }
  return 0;
}

}  // namespace lipdrive
