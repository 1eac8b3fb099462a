// `lipdrive check-config FILE`: validate a configuration file without starting anything.
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/outputs/make_outputs.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <memory>

namespace lipdrive {

void add_check_config_command(CLI::App& app) {
  auto file = std::make_shared<std::filesystem::path>();
  CLI::App* check = app.add_subcommand(
      "check-config",
      "Validate a configuration file without starting anything: the files it names are read as the daemon reads "
      "them (model, predictor, performer profile, voice model), audio devices opened once, GPIO lines looked up");
  check->add_option("FILE", *file, "configuration file")->required();
  check->callback([file] {
    const Config config = load_config(*file);
    // What `run` reads before it starts, with the same errors and exit codes.
    make_processor(config, load_performer(config));
    // The daemon runs on the video alone without a voice model it can use; the check says why.
    if (config.voice.enabled) load_voice(config);
    check_audio_inputs(config);
    check_outputs(config);
    const Config::Outputs& outputs = config.outputs;
    if (outputs.modbus_servers.empty() && outputs.modbus_clients.empty() && outputs.serial.empty() &&
        outputs.dmx.empty() && outputs.osc.empty() && !outputs.gpio.enabled)
      spdlog::warn("{}: no output is configured: the daemon would drive nothing", file->string());
    fmt::print("{}: ok\n", file->string());
  });
}

}  // namespace lipdrive
