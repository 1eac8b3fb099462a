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

}  // namespace lipdrive
