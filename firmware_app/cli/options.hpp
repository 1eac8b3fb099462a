// Checks of command-line options the commands share.
#pragma once

#include <CLI/CLI.hpp>

namespace lipdrive {

/// CLI::Range for a real number, which also refuses nan (CLI::Range lets it through: every
/// comparison with nan is false) and infinities.
CLI::Validator finite_range(double min, double max);

// A command's --out never names a file the same command reads: `process take.mpg --out
// take.mpg` would replace the take with its table, `calibrate --config C.toml --out C.toml` the
// configuration with a profile, `predictor convert --in x.dat --out x.dat` the only copy of the
// predictor.

/// Throws CommandError (exit 64, EX_USAGE) when the file `command`'s --out names is, by any
/// path (a link, `./`, another spelling), the file another of its options or arguments names.
/// A command calls it first thing in its callback.
void refuse_out_over_input(const CLI::App& command);

}  // namespace lipdrive
