// The configuration file (TOML): load_config, as `lipdrive run`, `check-config` and a reload
// read it. Every mistake must be a ConfigError naming the file, the key and the reason.
#include "firmware_app/config/config.hpp"
#include "fuzz_input.hpp"

#include <spdlog/spdlog.h>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool quiet = (spdlog::set_level(spdlog::level::off), true);
  (void)quiet;
  try {
    lipdrive::load_config(lipdrive::fuzz::input_file(data, size, ".toml"));
  } catch (const lipdrive::ConfigError&) {
  }
  return 0;
}
