// `lipdrive calibrate`: a performer's profile from a neutral capture and a range-of-motion
// capture, on the configured camera (live: follow the prompts) or a recording (--input: the
// first tracked frames are the neutral pose, the rest is the range of motion). For a model
// with expression shapes the neutral capture also fits the performer's identity, which the
// profile keeps and every later fit starts from. Camera,
// tracker and fit come from the configuration through the daemon's factory
// (config/factories.hpp).
#include "core/calibration.hpp"
#include "core/fitting.hpp"
#include "core/model_format.hpp"
#include "core/statistics.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/cli/options.hpp"
#include "firmware_app/cli/recording.hpp"
#include "firmware_app/daemon/rotated_camera.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/loaded_files.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "sim/simulated_camera.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
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

/// What the capture reads.
struct Source {
  std::unique_ptr<FrameSource> camera;
  SimulatedCamera* input = nullptr;  // --input's recording inside `camera`: what its kCorrupt lost
};

/// The configured camera, or the recording that stands in for it, turned as the camera is
/// ([camera] rotation).
Source open_source(const Config& config, const CalibrateOptions& options) {
  if (options.input.empty()) {
    // The configuration's simulated camera is a recording like --input: played once through,
    // its end ends the capture (looping, as the daemon replays it, it would never end).
    Config once = config;
    once.camera.sim.loop = false;
    return {.camera = make_source(once)};
  }
  auto recording = std::make_unique<SimulatedCamera>(open_recording(options.input));
  SimulatedCamera* input = recording.get();
  return {.camera = upright(std::move(recording), config.camera.rotation), .input = input};
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

/// The neutral capture: the measures of its tracked frames, the face's indices, and, for a
/// model with expression shapes, the landmarks and images the identity is fitted on.
struct NeutralCapture {
  std::unique_ptr<CalibrationCapture> measures = std::make_unique<CalibrationCapture>();
  std::vector<FacialMeasures> faces;
  std::vector<Landmarks2D> landmarks;
  std::vector<std::pair<cv::Mat, cv::Mat>> images;  // luma and Cr
  std::vector<double> quality;                      // the fit's (MouthMeasures::quality)

  void add(const FrameMeasurement& m, const cv::Mat& gray, const cv::Mat& cr, bool keep_images) {
    measures->add(m.measures);
    faces.push_back(facial_measures(m.landmarks));
    landmarks.push_back(m.landmarks);
    quality.push_back(m.measures.quality);
    if (keep_images) images.emplace_back(gray.clone(), cr.clone());
  }
};

/// The performer's identity (fit_identity over the neutral frames' landmarks, docs/method.md
/// 3) and rest point (fit_rest_expression on that identity, docs/arkit.md); the
/// processor is rebuilt on them and the neutral frames are measured again, so the profile's
/// rest values come from the fit the daemon will run.
PerformerIdentity fit_performer_identity(const Config& config, LoadedFiles& files, NeutralCapture& neutral,
                                         std::unique_ptr<FrameProcessor>& processor) {
  const MorphableModel& model = *files.model(config.model.file);
  PerformerIdentity identity;
  try {
    const Eigen::VectorXf alpha = fit_identity(model, config.model.landmark_set, neutral.landmarks);
    identity.model_fingerprint = files.model_fingerprint(config.model.file);
    identity.components = std::min(static_cast<int>(alpha.size()), kMaxFitComponents);
    for (int i = 0; i < identity.components; ++i) identity.alpha[static_cast<std::size_t>(i)] = alpha[i];
    FitSettings fit;
    fit.iterations = config.model.iterations;
    const FitOutput::Expressions rest =
        fit_rest_expression(model, config.model.landmark_set, neutral.landmarks, alpha, fit);
    identity.expressions = model.num_expressions();
    for (int e = 0; e < identity.expressions; ++e)
      identity.rest[static_cast<std::size_t>(e)] = static_cast<float>(rest[e]);
  } catch (const std::invalid_argument& e) {
    throw CommandError(fmt::format("{}: {}", config.model.file.string(), e.what()), kExitDataError);
  }
  PerformerProfile with_identity;
  with_identity.identity = identity;
  processor = make_processor(config, files, with_identity);
  const double mean_face_quality = median(neutral.quality);
  NeutralCapture again;
  for (const auto& [gray, cr] : neutral.images) {
    const FrameMeasurement& m = processor->process(gray, cr);
    if (m.tracked) again.add(m, gray, cr, false);
  }
  fmt::print("identity: {} components from {} neutral frames; fit quality at rest {:.3f} (mean face {:.3f})\n",
             identity.components, neutral.landmarks.size(), median(again.quality), mean_face_quality);
  neutral = std::move(again);
  return identity;
}

void run_calibrate(const CalibrateOptions& options) {
  // The profile the configuration names may be the one this writes; a recording stands in for the camera.
  const Config config =
      load_config(options.config, options.input.empty() ? ConfigUse::kCalibrateCamera : ConfigUse::kCalibrateInput);
  const std::filesystem::path out =
      options.out.empty() ? profile_path(config.performer.profiles_dir, options.performer) : options.out;
  const int neutral_frames = options.neutral_frames > 0 ? options.neutral_frames : config.performer.neutral_frames;
  const bool recording = !options.input.empty() || config.camera.type == Config::Camera::Type::kSim;
  const Source source = open_source(config, options);
  LoadedFiles files;
  // The mean face until the neutral capture gives the performer's identity (not one the
  // processor would fit of its own on the way, [model] auto_identity_frames).
  Config mean_face = config;
  mean_face.model.auto_identity_frames = 0;
  auto processor = make_processor(mean_face, files, PerformerProfile{});
  const bool fits_identity = files.model(config.model.file)->has_expressions();
  std::optional<PerformerIdentity> identity;

  NeutralCapture neutral;
  auto motion = std::make_unique<CalibrationCapture>();
  if (!recording) fmt::print(stderr, "Hold a relaxed, neutral face with the lips closed...\n");
  Frame frame;
  double motion_start_s = -1;
  RecordingDamage damage;  // --input's frames that could not be read: process judges them so too
  std::size_t frames = 0;
  for (;;) {
    const GrabStatus status = source.camera->grab(frame, std::chrono::milliseconds(200));
    if (status == GrabStatus::kEndOfStream) break;
    if (status == GrabStatus::kCorrupt && source.input)
      damage.add(*source.input->last_error(), source.input->lost_frames());
    if (status != GrabStatus::kFrame) continue;
    ++frames;
    const FrameMeasurement& m = processor->process(frame.gray, frame.cr);
    if (!m.tracked) continue;
    if (neutral.measures->size() < neutral_frames && !identity) {
      neutral.add(m, frame.gray, frame.cr, fits_identity);
      if (neutral.measures->size() < neutral_frames) continue;
      if (fits_identity) identity = fit_performer_identity(config, files, neutral, processor);
      if (!recording)
        fmt::print(stderr, "Now open wide, smile wide, round the lips (\"oo\"), close; repeat for {:.0f} s...\n",
                   options.motion_seconds);
      continue;
    }
    if (motion_start_s < 0) motion_start_s = frame.media_time_s;
    motion->add(m.measures);
    if (!recording && frame.media_time_s - motion_start_s >= options.motion_seconds) break;
  }
  if (source.input) damage.check(options.input, frames, source.input->independent_frames());
  const std::string what = source.camera->describe();
  if (neutral.measures->size() < neutral_frames)
    throw CommandError(fmt::format("{}: calibration failed: {} tracked frames, the neutral capture needs {}", what,
                                   neutral.measures->size(), neutral_frames),
                       kExitDataError);
  PerformerProfile profile;
  try {
    profile = calibrate(neutral.measures->samples(), motion->samples());
  } catch (const CalibrationError& e) {
    throw CommandError(fmt::format("{}: calibration failed: {}", what, e.what()), kExitDataError);
  }
  profile.face_indices = median_indices(neutral.faces);
  profile.identity = identity;
  const Compatibility check = model_compatibility(profile, *files.model(config.model.file));
  save_profile(out, options.performer, profile);
  fmt::print("{}: performer {} ({} neutral frames, {} motion frames)\n", out.string(), options.performer,
             neutral.measures->size(), motion->size());
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
  // The name is checked here, with --out too (it is written into the profile): a bad one is a command-line error.
  cmd->add_option("--performer", options->performer, "the performer's name (the profile file's name)")
      ->required()
      ->check(CLI::Validator(
          [](const std::string& name) {
            try {
              profile_path({}, name);
              return std::string();
            } catch (const std::invalid_argument& e) {
              return std::string(e.what());
            }
          },
          "NAME"));
  cmd->add_option("--input", options->input, "a recording instead of the configured camera");
  cmd->add_option("--out", options->out, "profile file (default: <profiles_dir>/<performer>.toml)");
  cmd->add_option("--neutral-frames", options->neutral_frames, "tracked frames of the neutral capture")
      ->check(CLI::Range(kMinNeutralFrames, CalibrationCapture::kCapacity));
  cmd->add_option("--motion-seconds", options->motion_seconds, "live camera: length of the range-of-motion capture")
      ->check(finite_range(1.0, 60.0));
  cmd->callback([options, cmd] {
    refuse_out_over_input(*cmd);
    run_calibrate(*options);
  });
}

}  // namespace lipdrive
