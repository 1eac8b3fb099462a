#include "firmware_app/command_error.hpp"
#include "firmware_app/commands.hpp"

#include <CLI/CLI.hpp>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <exception>

int main(int argc, char** argv) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("lipdrive"));
  spdlog::set_pattern("%^%l%$: %v");

  CLI::App app{"lipdrive: live mouth parameters from a head-mounted camera rig"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lipdrive 0.1.0");
  lipdrive::add_model_commands(app);
  lipdrive::add_eval_command(app);
  lipdrive::add_plot_command(app);
  lipdrive::add_fixture_command(app);
  lipdrive::add_process_command(app);
  lipdrive::add_calibrate_command(app);
  lipdrive::add_run_commands(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const lipdrive::CommandError& e) {
    spdlog::error("{}", e.what());
    return e.exit_code();
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return lipdrive::kExitFailure;
  }
  return 0;
}
