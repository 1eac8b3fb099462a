#include "firmware_app/cli/recording.hpp"

#include "firmware_app/cli/command_error.hpp"

#include <fmt/format.h>

#include <unistd.h>

namespace lipdrive {

SimulatedCamera open_recording(const std::filesystem::path& input) {
  std::error_code ec;
  if (!std::filesystem::exists(input, ec))
    throw CommandError(fmt::format("{}: no such file or folder", input.string()), kExitNoInput);
  if (::access(input.c_str(), R_OK | (std::filesystem::is_directory(input, ec) ? X_OK : 0)) != 0)
    throw CommandError(fmt::format("{}: permission denied", input.string()), kExitNoInput);
  SimulatedCameraOptions options;  // as fast as possible, no looping
  options.input = input;
  try {
    return SimulatedCamera(options);
  } catch (const SourceError& e) {
    throw CommandError(e.what(), kExitDataError);
  }
}

}  // namespace lipdrive
