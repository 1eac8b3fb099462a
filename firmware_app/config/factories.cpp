#include "firmware_app/config/factories.hpp"

#include "drivers/alsa_capture.hpp"
#include "drivers/v4l2_camera.hpp"
#ifdef LIPDRIVE_HAVE_LIBCAMERA
#include "drivers/libcamera_camera.hpp"
#endif
#include "core/model_format.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "firmware_app/daemon/rotated_camera.hpp"
#include "sim/ltc_generator.hpp"
#include "sim/simulated_audio.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace lipdrive {

namespace {

/// The camera of one configuration table ("camera" or "side_camera", for messages), as it
/// delivers its frames.
std::unique_ptr<FrameSource> open_camera(const Config::Camera& camera, const Config& config, std::string_view table,
                                         ReplayClock* clock = nullptr) {
  if (camera.type == Config::Camera::Type::kV4l2) return std::make_unique<V4l2Camera>(camera.v4l2);
#ifdef LIPDRIVE_HAVE_LIBCAMERA
  if (camera.type == Config::Camera::Type::kLibcamera) {
    const V4l2Options& format = camera.v4l2;
    try {
      return std::make_unique<LibcameraCamera>(LibcameraOptions{camera.libcamera_id, format.width, format.height,
                                                                format.frame_rate, format.controls.exposure_us,
                                                                camera.wait_when_absent});
    } catch (const SourceError& e) {
      throw ConfigError(fmt::format("{}: key {}.type: {}", config.file.string(), table, e.what()));
    }
  }
#endif
  try {
    return std::make_unique<SimulatedCamera>(camera.sim, clock);
  } catch (const SourceError& e) {
    throw ConfigError(fmt::format("{}: key {}.input: {}", config.file.string(), table, e.what()));
  }
}

/// open_camera()'s camera, its frames turned upright ([camera] rotation).
std::unique_ptr<FrameSource> make_camera(const Config::Camera& camera, const Config& config, std::string_view table,
                                         ReplayClock* clock = nullptr) {
  return upright(open_camera(camera, config, table, clock), camera.rotation);
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

std::unique_ptr<FrameSource> make_source(const Config& config, ReplayClock* clock) {
  return make_camera(config.camera, config, "camera", clock);
}

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
    case Config::Timecode::Source::kLtc:
      return std::make_unique<LtcTimecode>(make_ltc_input(timecode), timecode.rate,
                                           config.scheduling.realtime_priority);
  }
  return nullptr;
}

std::unique_ptr<VoiceRoom> make_voice_room(const Config& config, ReplayClock* clock, TakeSound* sound) {
  const Config::Voice& voice = config.voice;
  if (!voice.enabled) return nullptr;
  const std::string video_only = "the drive follows the video alone";
  VoiceModel model;
  try {
    model = load_voice(config);
  } catch (const CommandError& e) {
    spdlog::error("voice: {}; {}", e.what(), video_only);
    return nullptr;
  }
  const int rate = voice.alsa.sample_rate;
  std::unique_ptr<AudioSource> input;
  if (voice.input == Config::Voice::Input::kSim) {
    try {
      input = std::make_unique<SimulatedClipAudio>(SimulatedAudioOptions{.clip = config.camera.sim.input,
                                                                         .sample_rate = rate,
                                                                         .block_frames = rate / 100,
                                                                         .loop_s = clock ? clock->loop_s() : 0},
                                                   clock);
    } catch (const AudioSourceError& e) {
      spdlog::error("voice: {}; {}", e.what(), video_only);
      return nullptr;
    }
  } else {
    auto capture = std::make_unique<AlsaCapture>(voice.alsa);
    if (!capture->is_open())
      spdlog::error("voice input {}: {}; {} until it opens", capture->describe(), capture->reopen_error(), video_only);
    input = std::move(capture);
  }
  try {
    auto room = std::make_unique<VoiceRoom>(std::move(input), model, sound, config.scheduling.realtime_priority);
    spdlog::info("{}, model {} (delay {:.0f} ms: look-ahead {:.0f} ms + half the analysis window)", room->describe(),
                 voice.model.string(), model.delay_s() * 1e3,
                 1e3 * model.context.lookahead * model.features.hop / model.features.sample_rate);
    return room;
  } catch (const std::exception& e) {
    spdlog::error("voice: {}: {}; {}", voice.model.string(), e.what(), video_only);
    return nullptr;
  }
}

PerformerProfile load_performer(const Config& config) {
  if (config.performer.name.empty()) return PerformerProfile{};
  const PerformerProfile profile =
      load_profile(profile_path(config.performer.profiles_dir, config.performer.name), config.performer.name);
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
  FitOutput::Expressions rest = FitOutput::Expressions::Zero();
  // Used only when no identity below is the performer's.
  const AutoIdentity automatic{.model = loaded, .frames = model.auto_identity_frames};
  if (profile.identity && loaded->has_expressions()) {
    if (profile.identity->model_fingerprint == files.model_fingerprint(model.file)) {
      // Only a named performer's identity was read from a file; calibrate's own was just fitted to this model.
      if (!config.performer.name.empty())
        check_identity_fits(profile_path(config.performer.profiles_dir, config.performer.name), *profile.identity,
                            *loaded);
      identity = profile.identity->vector(loaded->num_components());
      rest = profile.identity->rest_weights();
    } else
      spdlog::warn(
          "performer {}: the profile's identity was fitted to another model than {}; fitting {} until "
          "`lipdrive calibrate` runs with this model",
          config.performer.name, model.file.string(),
          automatic.frames > 0 ? "an identity of its own ([model] auto_identity_frames)" : "the mean face");
  }
  try {
    return std::make_unique<FrameProcessor>(*loaded, model.landmark_set, fit, files.predictor(config.tracker.predictor),
                                            identity, rest, automatic, config.tracker.settings);
  } catch (const std::invalid_argument& e) {
    throw CommandError(fmt::format("{}: {}", model.file.string(), e.what()), kExitDataError);
  }
}

VoiceModel load_voice(const Config& config) {
  VoiceModel model = load_voice_model_file(config.voice.model);
  if (const int rate = config.voice.alsa.sample_rate; model.features.sample_rate != rate)
    throw ConfigError(
        fmt::format("{}: key voice.sample_rate: {}: the model was trained on sound at {} Hz, the input "
                    "delivers {} Hz",
                    config.file.string(), config.voice.model.string(), model.features.sample_rate, rate));
  return model;
}

void check_audio_inputs(const Config& config) {
  const auto probe = [&config](AlsaCaptureOptions options, std::string_view key) {
    options.must_open = true;
    try {
      AlsaCapture capture(options);
    } catch (const AudioSourceError& e) {
      throw ConfigError(fmt::format("{}: key {}: {}", config.file.string(), key, e.what()));
    }
  };
  const Config::Timecode& timecode = config.timecode;
  if (timecode.source == Config::Timecode::Source::kLtc && timecode.input == Config::Timecode::Input::kAlsa)
    probe(timecode.alsa, "timecode.device");
  if (config.voice.enabled && config.voice.input == Config::Voice::Input::kAlsa)
    probe(config.voice.alsa, "voice.device");
}

}  // namespace lipdrive
