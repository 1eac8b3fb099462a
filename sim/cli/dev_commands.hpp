// The developer commands of `lipdrive-dev`: tools the build, the tests and the developers use
// (fixture generators, the synthetic head, the fit demo), which the installed `lipdrive`
// does not carry.
//
// A command is one file, cmd_<name>.cpp, that registers itself with one line at namespace
// scope,
//
//   const dev::Registration registration(add_my_command);
//
// and one line in sim/cli/CMakeLists.txt that builds the file into lipdrive-dev.
#pragma once

#include <vector>

namespace CLI {
class App;
}

namespace lipdrive::dev {

using AddCommand = void (*)(CLI::App& app);

/// Every registered command, in link order.
std::vector<AddCommand>& commands();

struct Registration {
  explicit Registration(AddCommand add) { commands().push_back(add); }
};

}  // namespace lipdrive::dev
