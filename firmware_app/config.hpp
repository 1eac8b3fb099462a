// The daemon's configuration file (TOML; config/lipdrive.toml is the documented reference).
//
// Everything is validated when the file is loaded, before anything starts: unknown keys,
// wrong types, out-of-range values and missing files (model, predictor, sim input, v4l2
// device) all throw ConfigError, so a typo never silently falls back to a default.
#pragma once

#include "core/landmarks.hpp"
#include "drivers/v4l2_camera.hpp"
#include "firmware_app/command_error.hpp"
#include "sim/simulated_camera.hpp"

#include <spdlog/common.h>

#include <filesystem>
#include <string>

namespace lipdrive {

/// "FILE: key KEY: reason"; exits with kExitConfig.
class ConfigError : public CommandError {
 public:
  explicit ConfigError(const std::string& message) : CommandError(message, kExitConfig) {}
};

struct Config {
  std::filesystem::path file;  // where it was loaded from, for messages

  spdlog::level::level_enum log_level = spdlog::level::info;

  struct Model {
    std::filesystem::path file;  // resolved: never empty
    LandmarkSet landmark_set = kDefaultLandmarkSet;
    int iterations = 3;
  } model;

  struct Tracker {
    std::filesystem::path predictor;
  } tracker;

  struct Camera {
    enum class Type { kSim, kV4l2 };
    Type type = Type::kSim;
    SimulatedCameraOptions sim;  // input resolved: never empty
    V4l2Options v4l2;
  } camera;

  struct Recording {
    std::filesystem::path dir;
    bool start = false;
    int flush_interval_ms = 500;
  } recording;

  struct Status {
    int print_interval_ms = 1000;  // 0 = off
  } status;
};

/// Reads and validates a configuration file. Throws ConfigError naming the file, the key
/// and the reason.
Config load_config(const std::filesystem::path& file);

}  // namespace lipdrive
