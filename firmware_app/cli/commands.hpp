// The subcommands of `lipdrive`, one file each (cmd_<name>.cpp); each registers itself on the
// top-level CLI. Developer tools (fixture generators, the synthetic head, the fit demo) are
// not here: they are `lipdrive-dev` (sim/cli/).
#pragma once

namespace CLI {
class App;
}

namespace lipdrive {

void add_model_command(CLI::App& app);         // model build | info | render
void add_process_command(CLI::App& app);       // process
void add_voice_command(CLI::App& app);         // voice train | eval
void add_eval_command(CLI::App& app);          // eval
void add_plot_command(CLI::App& app);          // plot
void add_calibrate_command(CLI::App& app);     // calibrate
void add_run_command(CLI::App& app);           // run: the daemon
void add_check_config_command(CLI::App& app);  // check-config
void add_predictor_command(CLI::App& app);     // predictor convert | info

}  // namespace lipdrive
