// The one way a subcommand reports failure: a message for the user and an exit code
// (sysexits.h values where one fits).
#pragma once

#include <stdexcept>
#include <string>

namespace lipdrive {

inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 64;      // EX_USAGE: the command line is wrong
inline constexpr int kExitDataError = 65;  // EX_DATAERR: input is malformed
inline constexpr int kExitNoInput = 66;    // EX_NOINPUT: input missing or unreadable
inline constexpr int kExitCantCreate = 73;  // EX_CANTCREAT: an output file cannot be made
inline constexpr int kExitIoError = 74;     // EX_IOERR: writing an output failed (a full disk)
inline constexpr int kExitTryAgain = 75;    // EX_TEMPFAIL: no name server answered; the unit restarts
inline constexpr int kExitConfig = 78;     // EX_CONFIG: bad configuration

class CommandError : public std::runtime_error {
 public:
  CommandError(const std::string& message, int exit_code = kExitFailure)
      : std::runtime_error(message), exit_code_(exit_code) {}
  int exit_code() const { return exit_code_; }

 private:
  int exit_code_;
};

}  // namespace lipdrive
