#include "firmware_app/config/factories.hpp"

#include "drivers/alsa_capture.hpp"
#include "drivers/v4l2_camera.hpp"
#ifdef LIPDRIVE_HAVE_LIBCAMERA
#include "drivers/libcamera_camera.hpp"
#endif
#include "core/model_format.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "sim/ltc_generator.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace lipdrive {

namespace {

/// The camera of one configuration table ("camera" or "side_camera", for messages).
std::unique_ptr<FrameSource> make_camera(const Config::Camera& camera, const Config& config, std::string_view table) {
  if (camera.type == Config::Camera::Type::kV4l2) return std::make_unique<V4l2Camera>(camera.v4l2);
#ifdef LIPDRIVE_HAVE_LIBCAMERA
  if (camera.type == Config::Camera::Type::kLibcamera) {
    const V4l2Options& format = camera.v4l2;
    try {
      return std::make_unique<LibcameraCamera>(
          LibcameraOptions{camera.libcamera_id, format.width, format.height, format.frame_rate});
    } catch (const SourceError& e) {
      throw ConfigError(fmt::format("{}: key {}.type: {}", config.file.string(), table, e.what()));
    }
  }
#endif
  try {
    return std::make_unique<SimulatedCamera>(camera.sim);
  } catch (const SourceError& e) {
    throw ConfigError(fmt::format("{}: key {}.input: {}", config.file.string(), table, e.what()));
  }
}

/// [timecode]'s LTC input. A sound card input that cannot be opened yet is retried in the
/// background: the daemon runs without timecode meanwhile.
std::unique_ptr<AudioSource> make_ltc_input(const Config::Timecode& timecode) {
  if (timecode.input == Config::Timecode::Input::kSim) return std::make_unique<SimulatedLtcAudio>(timecode.sim);
  auto capture = std::make_unique<AlsaCapture>(timecode.alsa);
  if (!capture->is_open())
    spdlog::error("LTC input {}: {}; frames go unstamped until it opens", capture->describe(), capture->reopen_error());
  return capture;
}

}  // namespace

std::unique_ptr<FrameSource> make_source(const Config& config) { return make_camera(config.camera, config, "camera"); }

std::unique_ptr<SideCamera> make_side_camera(const Config& config) {
  if (!config.side_camera) return nullptr;
  return std::make_unique<SideCamera>(make_camera(*config.side_camera, config, "side_camera"),
                                      SideProfileSettings{.facing = config.side_facing},
                                      config.performer.neutral_frames);
}

std::unique_ptr<TimecodeSource> make_timecode(const Config& config) {
  const Config::Timecode& timecode = config.timecode;
  switch (timecode.source) {
    case Config::Timecode::Source::kNone: return nullptr;
    case Config::Timecode::Source::kClock: return std::make_unique<ClockTimecode>(timecode.rate);
    case Config::Timecode::Source::kLtc: return std::make_unique<LtcTimecode>(make_ltc_input(timecode), timecode.rate);
  }
  return nullptr;
}

PerformerProfile load_performer(const Config& config) {
  if (config.performer.name.empty()) return PerformerProfile{};
  const PerformerProfile profile = load_profile(profile_path(config.performer.profiles_dir, config.performer.name));
  spdlog::info("performer {}: open [{:.3f}, {:.3f}], width [{:.3f}, {:.3f}], protrusion [{:.3f}, {:.3f}]{}",
               config.performer.name, profile.open.min, profile.open.max, profile.width.min, profile.width.max,
               profile.protrusion.min, profile.protrusion.max,
               profile.identity ? fmt::format(", identity of {} components", profile.identity->components) : "");
  return profile;
}

std::unique_ptr<FrameProcessor> make_processor(const Config& config, LoadedFiles& files,
                                               const PerformerProfile& profile) {
  const Config::Model& model = config.model;
  const std::shared_ptr<const MorphableModel> loaded = files.model(model.file);
  FitSettings fit;
  fit.iterations = model.iterations;
  Eigen::VectorXf identity;
  if (profile.identity && loaded->has_expressions()) {
    if (profile.identity->model_fingerprint == identity_fingerprint(*loaded))
      identity = profile.identity->vector(loaded->num_components());
    else
      spdlog::warn("performer {}: the profile's identity was fitted to another model than {}; fitting the mean face "
                   "until `lipdrive calibrate` runs with this model",
                   config.performer.name, model.file.string());
  }
  try {
    return std::make_unique<FrameProcessor>(*loaded, model.landmark_set, fit,
                                            files.predictor(config.tracker.predictor), identity);
  } catch (const std::invalid_argument& e) {
    throw CommandError(fmt::format("{}: {}", model.file.string(), e.what()), kExitDataError);
  }
}

void check_audio_inputs(const Config& config) {
  const Config::Timecode& timecode = config.timecode;
  if (timecode.source == Config::Timecode::Source::kLtc && timecode.input == Config::Timecode::Input::kAlsa) {
    AlsaCaptureOptions probe = timecode.alsa;
    probe.must_open = true;
    try {
      AlsaCapture capture(probe);
    } catch (const AudioSourceError& e) {
      throw ConfigError(fmt::format("{}: key timecode.device: {}", config.file.string(), e.what()));
    }
  }
}

}  // namespace lipdrive
