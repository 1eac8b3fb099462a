// Each subcommand family registers itself on the top-level CLI.
#pragma once

namespace CLI {
class App;
}

namespace lipdrive {

/// `lipdrive model ...`: build | info (cmd_model.cpp), which also registers
/// generate-head | render (cmd_model_head.cpp) and fit-demo (cmd_fit_demo.cpp).
void add_model_commands(CLI::App& app);
void add_model_head_commands(CLI::App& model);
void add_fit_demo_command(CLI::App& model);

/// `lipdrive eval` (cmd_eval.cpp) and `lipdrive plot` (cmd_plot.cpp).
void add_eval_command(CLI::App& app);
void add_plot_command(CLI::App& app);

/// `lipdrive fixture talking-face` (cmd_fixture.cpp).
void add_fixture_command(CLI::App& app);

/// `lipdrive process` (cmd_process.cpp).
void add_process_command(CLI::App& app);

/// `lipdrive calibrate` (cmd_calibrate.cpp).
void add_calibrate_command(CLI::App& app);

/// `lipdrive run` (the daemon) and `lipdrive check-config` (cmd_run.cpp).
void add_run_commands(CLI::App& app);

}  // namespace lipdrive
