// `lipdrive calibrate`: a performer's profile from a neutral capture and a range-of-motion
// capture, on the configured camera (live: follow the prompts) or a recording (--input: the
// first tracked frames are the neutral pose, the rest is the range of motion). Camera,
// tracker and fit come from the configuration through the daemon's factory
// (config/factories.hpp).
#include "core/calibration.hpp"
#include "core/statistics.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "sim/simulated_camera.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <memory>
#include <vector>

namespace lipdrive {
namespace {

struct CalibrateOptions {
  std::filesystem::path config;
  std::string performer;
  std::filesystem::path input;  // empty: the configured camera
  std::filesystem::path out;    // empty: the performer's profile in [performer] profiles_dir
  int neutral_frames = 0;       // 0: [performer] neutral_frames
  double motion_seconds = 10;   // live cameras; a recording runs to its end
};

std::unique_ptr<FrameSource> open_source(const Config& config, const CalibrateOptions& options) {
  if (options.input.empty()) return make_source(config);
  SimulatedCameraOptions sim;
  sim.input = options.input;
  sim.real_time = false;
  sim.loop = false;
  try {
    return std::make_unique<SimulatedCamera>(sim);
  } catch (const SourceError& e) {
    throw CommandError(e.what(), kExitNoInput);
  }
}

/// Per index, the median over the neutral frames: a blink or a mistracked frame moves nothing.
std::array<double, kNumFacialIndices> median_indices(const std::vector<FacialMeasures>& faces) {
  std::array<double, kNumFacialIndices> medians{};
  std::vector<double> values(faces.size());
  for (std::size_t i = 0; i < medians.size(); ++i) {
    std::ranges::transform(faces, values.begin(), [i](const FacialMeasures& face) { return face.indices[i]; });
    medians[i] = median(values);
  }
  return medians;
}

void run_calibrate(const CalibrateOptions& options) {
  const Config config = load_config(options.config);
  const std::filesystem::path out =
      options.out.empty() ? profile_path(config.performer.profiles_dir, options.performer) : options.out;
  const int neutral_frames = options.neutral_frames > 0 ? options.neutral_frames : config.performer.neutral_frames;
  const bool recording = !options.input.empty() || config.camera.type == Config::Camera::Type::kSim;
  auto source = open_source(config, options);
  auto processor = make_processor(config);

  auto neutral = std::make_unique<CalibrationCapture>();
  std::vector<FacialMeasures> neutral_faces;
  auto motion = std::make_unique<CalibrationCapture>();
  if (!recording) fmt::print(stderr, "Hold a relaxed, neutral face with the lips closed...\n");
  Frame frame;
  double motion_start_s = -1;
  for (;;) {
    const GrabStatus status = source->grab(frame, std::chrono::milliseconds(200));
    if (status == GrabStatus::kEndOfStream) break;
    if (status != GrabStatus::kFrame) continue;
    const FrameMeasurement& m = processor->process(frame.gray);
    if (!m.tracked) continue;
    if (neutral->size() < neutral_frames) {
      neutral->add(m.measures);
      neutral_faces.push_back(facial_measures(m.landmarks));
      if (neutral->size() == neutral_frames && !recording)
        fmt::print(stderr, "Now open wide, smile wide, round the lips (\"oo\"), close; repeat for {:.0f} s...\n",
                   options.motion_seconds);
      continue;
    }
    if (motion_start_s < 0) motion_start_s = frame.media_time_s;
    motion->add(m.measures);
    if (!recording && frame.media_time_s - motion_start_s >= options.motion_seconds) break;
  }
  PerformerProfile profile;
  try {
    profile = calibrate(neutral->samples(), motion->samples());
  } catch (const CalibrationError& e) {
    throw CommandError(fmt::format("calibration failed: {}", e.what()), kExitDataError);
  }
  profile.face_indices = median_indices(neutral_faces);
  const Compatibility check = model_compatibility(profile, load_model_file(config.model.file));
  save_profile(out, options.performer, profile);
  fmt::print("{}: performer {} ({} neutral frames, {} motion frames)\n", out.string(), options.performer,
             neutral->size(), motion->size());
  fmt::print("  open       {:.3f} .. {:.3f}\n  width      {:.3f} .. {:.3f}\n  protrusion {:.3f} .. {:.3f}\n",
             profile.open.min, profile.open.max, profile.width.min, profile.width.max, profile.protrusion.min,
             profile.protrusion.max);
  fmt::print("  vertical mouth height {:.2f} ({}; model {}), mouth width {:.2f} ({}; model {})\n",
             (*profile.face_indices)[kVerticalMouthHeightIndex],
             index_class_name(check.performer.vertical_mouth_height),
             index_class_name(check.model.vertical_mouth_height), (*profile.face_indices)[kMouthWidthIndex],
             index_class_name(check.performer.mouth_width), index_class_name(check.model.mouth_width));
  if (check.warn)
    fmt::print(
        "  warning: the performer's vertical mouth height is {} and the model's {}: expect clearly worse lips "
        "(docs/method.md 6); a model of a closer head drives better\n",
        index_class_name(check.performer.vertical_mouth_height), index_class_name(check.model.vertical_mouth_height));
}

}  // namespace

void add_calibrate_command(CLI::App& app) {
  auto options = std::make_shared<CalibrateOptions>();
  CLI::App* cmd = app.add_subcommand("calibrate", "A performer's profile from their neutral face and range of motion");
  cmd->add_option("--config", options->config, "configuration file: model, tracker, camera, [performer]")->required();
  cmd->add_option("--performer", options->performer, "the performer's name (the profile file's name)")->required();
  cmd->add_option("--input", options->input, "a recording instead of the configured camera");
  cmd->add_option("--out", options->out, "profile file (default: <profiles_dir>/<performer>.toml)");
  cmd->add_option("--neutral-frames", options->neutral_frames, "tracked frames of the neutral capture")
      ->check(CLI::Range(kMinNeutralFrames, CalibrationCapture::kCapacity));
  cmd->add_option("--motion-seconds", options->motion_seconds, "live camera: length of the range-of-motion capture")
      ->check(CLI::Range(1.0, 60.0));
  cmd->callback([options] { run_calibrate(*options); });
}

}  // namespace lipdrive
