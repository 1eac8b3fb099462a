// `lipdrive`: the product's executable: the daemon and the offline commands a studio uses.
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/cli/run_cli.hpp"

#include <CLI/CLI.hpp>

int main(int argc, char** argv) {
  lipdrive::set_up_logging("lipdrive");
  CLI::App app{"lipdrive: live mouth parameters from a head-mounted camera rig"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "lipdrive 0.1.0");
  lipdrive::add_model_command(app);
  lipdrive::add_eval_command(app);
  lipdrive::add_plot_command(app);
  lipdrive::add_process_command(app);
  lipdrive::add_voice_command(app);
  lipdrive::add_calibrate_command(app);
  lipdrive::add_run_command(app);
  lipdrive::add_check_config_command(app);
  lipdrive::add_predictor_command(app);
  return lipdrive::run_cli(app, argc, argv);
}
