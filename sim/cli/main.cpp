// `lipdrive-dev`: the developer tools (dev_commands.hpp). Built by default, used by the build
// (default models, fixtures) and the tests; `cmake --install` does not install it.
#include "firmware_app/cli/run_cli.hpp"
#include "sim/cli/dev_commands.hpp"

#include <CLI/CLI.hpp>

namespace lipdrive::dev {

std::vector<AddCommand>& commands() {
  static std::vector<AddCommand> registered;  // filled before main() by each command's Registration
  return registered;
}

}  // namespace lipdrive::dev

int main(int argc, char** argv) {
  lipdrive::set_up_logging("lipdrive-dev");
  CLI::App app{"lipdrive-dev: developer tools of lipdrive (test fixtures, the synthetic head, the fit demo)"};
  app.require_subcommand(1);
  for (const lipdrive::dev::AddCommand add : lipdrive::dev::commands()) add(app);
  return lipdrive::run_cli(app, argc, argv);
}
