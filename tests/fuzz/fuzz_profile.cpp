// Performer profiles (TOML, written by `lipdrive calibrate`, edited by hand): load_profile.
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    lipdrive::load_profile(lipdrive::fuzz::input_file(data, size, ".toml"), "alex");  // the seeds' performer
  } catch (const lipdrive::CommandError&) {
  }
  return 0;
}
