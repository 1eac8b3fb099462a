// `lipdrive process INPUT`: the offline pipeline over a recording (video, image or folder
// of images): landmarks -> 3DMM fit -> mouth measures, one CSV row per frame
// (tables/measures_csv.hpp). Video frames are tracked from one to the next; images (a
// folder or a single one) are unrelated, so each is detected afresh. The tracker and the
// fit are built by the daemon's factory (config/factories.hpp) from `--config FILE`, or
// from the defaults, so offline results are the rig's.
//
// A second thread decodes ahead into a small ring of preallocated luma buffers, so decoding
// overlaps tracking and fitting on a 2-core board; rows still come out in frame order.
#include "core/calibration.hpp"
#include "core/image_rotation.hpp"
#include "core/side_profile.hpp"
#include "core/statistics.hpp"
#include "core/voice_training.hpp"
#include "drivers/audio_file.hpp"
#include "drivers/clock.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/cli/options.hpp"
#include "firmware_app/cli/recording.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/paths.hpp"
#include "firmware_app/config/predictor_file.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/daemon/rotated_camera.hpp"
#include "firmware_app/tables/measures_csv.hpp"
#include "sim/simulated_camera.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <climits>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

namespace lipdrive {
namespace {

struct ProcessOptions {
  std::filesystem::path input;
  std::filesystem::path out;     // empty: stdout
  std::filesystem::path config;  // empty: the defaults
  // Each overrides the configuration's (or the default) when given.
  std::filesystem::path model;
  std::string landmark_set;
  std::filesystem::path predictor;
  bool include_landmarks = false;
  bool stats = false;
  std::filesystem::path side;         // side-camera recording, frame for frame with the input
  std::optional<std::string> side_facing;  // where the face looks in the side view; else [side_camera] facing
  int side_neutral_frames = 15;       // its first frames: the neutral pose the reference is fixed on
  std::string timecode;               // the first frame's timecode: adds the timecode column
  double timecode_fps = 25;
  std::filesystem::path voice;  // a voice model: adds the voice's columns from the clip's sound
  std::optional<int> rotate;       // degrees clockwise that stand the frames upright; else [camera] rotation
  std::optional<int> side_rotate;  // the same for --side; else [side_camera] rotation
};

/// --rotate or --side-rotate when given, else the configured camera's rotation.
Rotation rotation_of(const std::optional<int>& option, Rotation configured) {
  return option ? *rotation_from_degrees(*option) : configured;
}

/// --voice: the voice model's measures for every frame of the clip, from its sound alone.
class VoiceColumns {
 public:
  VoiceColumns(const std::filesystem::path& model_file, const std::filesystem::path& clip)
      : model_(load_voice_model_file(model_file)) {
    try {
      const DecodedAudio sound = decode_audio(clip, model_.features.sample_rate);
      start_s_ = sound.start_s;
      outputs_ = predict_frames(model_, sound.samples);
    } catch (const AudioSourceError& e) {
      throw CommandError(e.what(), kExitDataError);
    }
  }
  static constexpr const char* kHeader = ",open_voice,width_voice,protrusion_voice,seal_voice";
  void append(fmt::memory_buffer& row, double media_time_s) const {
    const VoiceOutput& out = output_at(model_, outputs_, media_time_s - start_s_);
    for (const float value : out.values) fmt::format_to(std::back_inserter(row), ",{:.5f}", value);
  }

 private:
  VoiceModel model_;
  double start_s_ = 0;
  std::vector<VoiceOutput> outputs_;
};

/// --timecode START at --timecode-fps: the start's frame number and the rate; nullopt without.
std::optional<std::pair<std::int32_t, TimecodeRate>> timecode_start(const ProcessOptions& options) {
  if (options.timecode.empty()) return std::nullopt;
  const auto rate = rate_from_fps(options.timecode_fps);
  if (!rate)
    throw CLI::ValidationError("--timecode-fps",
                               fmt::format("must be 24, 25, 29.97 (drop-frame) or 30, got {}", options.timecode_fps));
  const auto label = parse_timecode(options.timecode);
  const auto frame = label ? frame_from_timecode(*label, *rate) : std::nullopt;
  if (!frame)
    throw CLI::ValidationError("--timecode", fmt::format("\"{}\" is not a timecode at {} fps (HH:MM:SS:FF)",
                                                         options.timecode, rate_name(*rate)));
  return std::pair{*frame, *rate};
}

/// The side-camera recording of a take: protrusion_side for each front frame (docs/method.md 4),
/// the reference fixed on its first frames, which must show the performer at rest.
class SideInput {
 public:
  /// The recording's frames turned by `rotation` first, as the side camera's are.
  SideInput(const ProcessOptions& options, ProfileFacing facing, Rotation rotation)
      : meter_(SideProfileSettings{.facing = facing}), camera_(open(options.side, rotation)) {
    std::vector<cv::Mat> neutral;
    const std::unique_ptr<FrameSource> first = open(options.side, rotation);
    Frame frame;
    for (GrabStatus status; static_cast<int>(neutral.size()) < options.side_neutral_frames &&
                            (status = first->grab(frame, std::chrono::milliseconds(0))) != GrabStatus::kEndOfStream;) {
      if (status == GrabStatus::kFrame) neutral.push_back(frame.gray.clone());
    }
    try {
      reference_ = calibrate_side(meter_, neutral);
    } catch (const SideCalibrationError& e) {
      throw CommandError(fmt::format("{}: {}", options.side.string(), e.what()), kExitDataError);
    }
  }

  /// The next side frame's protrusion; nullopt when the recording ended or the profile could
  /// not be measured.
  std::optional<double> next() {
    Frame frame;
    GrabStatus status;
    while ((status = camera_->grab(frame, std::chrono::milliseconds(0))) == GrabStatus::kTimeout) {
    }
    if (status != GrabStatus::kFrame) return std::nullopt;
    const SideMeasure measure = meter_.measure(frame.gray, reference_);
    return measure.ok() ? std::optional(measure.protrusion) : std::nullopt;
  }

 private:
  static std::unique_ptr<FrameSource> open(const std::filesystem::path& recording, Rotation rotation) {
    return upright(std::make_unique<SimulatedCamera>(open_recording(recording)), rotation);
  }

  SideProfileMeter meter_;
  std::unique_ptr<FrameSource> camera_;
  SideReference reference_;
};

/// What the decoder thread hands over, one slot of the ring.
struct DecodedFrame {
  enum class Kind { kFrame, kCorrupt, kEnd, kError };
  Kind kind = Kind::kEnd;
  cv::Mat gray;  // reused: copyTo keeps the buffer while the frame size stays the same
  cv::Mat cr;    // the same; empty from a monochrome source
  std::uint64_t sequence = 0;
  double media_time_s = 0;
  std::string source;
  std::string error;  // kCorrupt, kError
  std::optional<std::int64_t> lost;  // kCorrupt: the frames it stands for (SimulatedCamera::lost_frames)
  double decode_ms = 0;
};

/// A bounded single-producer, single-consumer queue of preallocated frames. The decoder
/// fills the slot after the last full one; the consumer reads the oldest full slot.
class FrameRing {
 public:
  explicit FrameRing(std::size_t slots) : slots_(slots) {}

  /// Producer: the next free slot, waiting while all are full; nullptr once closed.
  DecodedFrame* free_slot() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return closed_ || full_ < slots_.size(); });
    return closed_ ? nullptr : &slots_[(head_ + full_) % slots_.size()];
  }
  void publish() {
    {
      std::lock_guard lock(mutex_);
      ++full_;
    }
    changed_.notify_all();
  }
  /// Consumer: the oldest full slot, waiting while none is.
  DecodedFrame& oldest() {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return full_ > 0; });
    return slots_[head_];
  }
  void release() {
    {
      std::lock_guard lock(mutex_);
      head_ = (head_ + 1) % slots_.size();
      --full_;
    }
    changed_.notify_all();
  }
  /// Consumer: stop the producer (it returns from free_slot with nullptr).
  void close() {
    {
      std::lock_guard lock(mutex_);
      closed_ = true;
    }
    changed_.notify_all();
  }

 private:
  std::vector<DecodedFrame> slots_;
  std::size_t head_ = 0, full_ = 0;
  bool closed_ = false;
  std::mutex mutex_;
  std::condition_variable changed_;
};

void decode_all(SimulatedCamera& camera, Rotation rotation, FrameRing& ring) {
  Frame frame;
  for (;;) {
    DecodedFrame* slot = ring.free_slot();
    if (!slot) return;
    const std::int64_t start = monotonic_ns();
    try {
      GrabStatus status;
      do status = camera.grab(frame, std::chrono::milliseconds(1000));
      while (status == GrabStatus::kTimeout);
      switch (status) {
        case GrabStatus::kFrame:
          slot->kind = DecodedFrame::Kind::kFrame;
          rotate_plane(frame.gray, slot->gray, rotation);
          rotate_plane(frame.cr, slot->cr, rotation);
          slot->sequence = frame.sequence;
          slot->media_time_s = frame.media_time_s;
          slot->source.assign(frame.source);
          break;
        case GrabStatus::kCorrupt:
          slot->kind = DecodedFrame::Kind::kCorrupt;
          slot->error = camera.last_error().value_or("a frame could not be decoded");
          slot->lost = camera.lost_frames();
          break;
        default: slot->kind = DecodedFrame::Kind::kEnd;
      }
    } catch (const std::exception& e) {
      slot->kind = DecodedFrame::Kind::kError;
      slot->error = e.what();
    }
    slot->decode_ms = ms_since(start);
    const bool last = slot->kind == DecodedFrame::Kind::kEnd || slot->kind == DecodedFrame::Kind::kError;
    ring.publish();
    if (last) return;
  }
}

/// The run's temporary --out file, for end_without_temporary() (empty: none).
char temporary_file[PATH_MAX] = {};

/// Ctrl-C, a kill or a closed terminal ends the run where it stands, as the signal's default
/// action does, and takes the temporary file with it: the output stays as it was. (unlink()
/// and raise() are async-signal-safe; the signal, blocked while its handler runs, acts as the
/// handler returns.)
extern "C" void end_without_temporary(int signal) {
  if (temporary_file[0] != '\0') ::unlink(temporary_file);
  ::signal(signal, SIG_DFL);
  ::raise(signal);
}

/// Installs end_without_temporary() for SIGINT, SIGTERM and SIGHUP, but not for one this process
/// was told to ignore (nohup's SIGHUP, the SIGINT of a shell's background job).
void end_signals_without(const std::filesystem::path& temporary) {
  if (temporary.empty() || temporary.native().size() >= sizeof temporary_file) return;
  std::memcpy(temporary_file, temporary.c_str(), temporary.native().size() + 1);
  struct sigaction action {};
  action.sa_handler = end_without_temporary;
  sigemptyset(&action.sa_mask);
  for (const int signal : {SIGINT, SIGTERM, SIGHUP}) {
    struct sigaction before {};
    if (::sigaction(signal, nullptr, &before) == 0 && before.sa_handler != SIG_IGN)
      ::sigaction(signal, &action, nullptr);
  }
}

/// Per-stage latencies for --stats.
struct StageTimes {
  std::vector<double> decode, landmarks, fit, measures;
};

void print_stats(const StageTimes& times, std::size_t frames, double seconds) {
  fmt::print(stderr, "{:<10} {:>10} {:>10} {:>8}\n", "stage", "median ms", "p99 ms", "frames");
  const auto line = [](const char* name, std::vector<double> v) {
    fmt::print(stderr, "{:<10} {:>10.3f} {:>10.3f} {:>8}\n", name, median(v), quantile(v, 0.99), v.size());
  };
  line("decode", times.decode);
  line("landmarks", times.landmarks);
  line("fit", times.fit);
  line("measures", times.measures);
  fmt::print(stderr, "{} frames in {:.3f} s: {:.1f} frames/s (after loading)\n", frames, seconds,
             static_cast<double>(frames) / seconds);
}

/// --config (or the defaults), with the options given on top.
Config config_for(const ProcessOptions& options) {
  Config config;  // the defaults
  if (!options.config.empty()) config = load_config(options.config, ConfigUse::kOffline);
  if (!options.model.empty()) config.model.file = options.model;
  if (!options.landmark_set.empty()) config.model.landmark_set = *parse_landmark_set(options.landmark_set);
  if (!options.predictor.empty()) config.tracker.predictor = options.predictor;
  return config;
}

void run_process(const ProcessOptions& options) {
  const auto timecode = timecode_start(options);
  SimulatedCamera camera = open_recording(options.input);
  Config config = config_for(options);
  if (camera.independent_frames()) config.tracker.settings.still_cascade = load_still_cascade();
  // The performer's profile (the defaults without one): the fit's identity, and the signals the
  // ARKit weights of a model without expression shapes come from.
  const PerformerProfile profile = load_performer(config);
  const std::unique_ptr<FrameProcessor> processor = make_processor(config, profile);
  const Rotation rotation = rotation_of(options.rotate, config.camera.rotation);
  fit_take_identity(options.input, rotation, *processor);
  std::optional<SideInput> side;
  if (!options.side.empty()) {
    const ProfileFacing facing = !options.side_facing             ? config.side_facing
                                 : *options.side_facing == "left" ? ProfileFacing::kLeft
                                                                  : ProfileFacing::kRight;
    side.emplace(options, facing, rotation_of(options.side_rotate, config.side_rotation));
  }
  std::optional<VoiceColumns> voice;
  if (!options.voice.empty()) voice.emplace(options.voice, options.input);

  // The rows replace the file only once written: a mistake in an input, an error before the
  // first row or a process stopped halfway leaves the file as it was (FileReplacement).
  std::optional<FileReplacement> file;
  if (!options.out.empty()) {
    file.emplace(options.out);
    end_signals_without(file->temporary());
  }
  std::ostream& out = file ? file->stream() : std::cout;
  if (timecode)
    out << "# timecode_start " << format_frame(timecode->first, timecode->second).view() << " at "
        << rate_name(timecode->second) << " fps\n";
  out << measures_csv_header(options.include_landmarks) << (side ? ",protrusion_side" : "")
      << (timecode ? ",timecode" : "") << (voice ? VoiceColumns::kHeader : "") << '\n';

  const bool independent = camera.independent_frames();
  const bool progress = ::isatty(STDERR_FILENO) == 1;
  StageTimes times;
  std::size_t rows = 0, tracked_rows = 0;
  std::optional<std::string> decode_error;  // the input stopped being readable
  RecordingDamage damage;                   // pictures or frames that could not be decoded
  fmt::memory_buffer row;

  const std::int64_t start = monotonic_ns();
  FrameRing ring(4);
  std::thread decoder(decode_all, std::ref(camera), rotation, std::ref(ring));
  // Stops and joins the decoder however this scope is left.
  const auto stop_decoder = [&](std::thread* t) {
    ring.close();
    t->join();
  };
  const std::unique_ptr<std::thread, decltype(stop_decoder)> decoder_guard(&decoder, stop_decoder);

  for (;;) {
    DecodedFrame& frame = ring.oldest();
    if (frame.kind == DecodedFrame::Kind::kEnd) break;
    if (frame.kind == DecodedFrame::Kind::kError) {
      decode_error = frame.error;
      break;
    }
    if (frame.kind == DecodedFrame::Kind::kCorrupt) {
      // Each one named as it comes (a folder may hold several); the others are processed.
      damage.add(frame.error, frame.lost);
      ring.release();
      continue;
    }
    times.decode.push_back(frame.decode_ms);
    if (independent) processor->forget(FaceTracker::Next::kStill);
    const FrameMeasurement& result = processor->process(frame.gray, frame.cr);
    times.landmarks.push_back(result.landmarks_ms);
    if (!std::isnan(result.fit_ms)) times.fit.push_back(result.fit_ms);
    if (result.tracked) times.measures.push_back(result.measures_ms);
    DriveSignals signals;
    if (result.tracked) {
      signals = drive_signals(result.measures, result.visemes, profile);
      processor->set_arkit(signals);
    }
    row.clear();
    append_measures_csv_row(row, {frame.sequence, frame.media_time_s, frame.source},
                            result.tracked ? &result.measures : nullptr, result.visemes, signals.arkit(),
                            options.include_landmarks ? &result.landmarks : nullptr);
    if (side) {
      const std::optional<double> protrusion = side->next();
      fmt::format_to(std::back_inserter(row), ",");
      if (protrusion) fmt::format_to(std::back_inserter(row), "{:.5f}", *protrusion);
    }
    if (timecode) {
      // The frame's place in the recording from the start's timecode, like the sound
      // department's recorder stamping the same take: the timecode frame its start falls in.
      // Its time is as the container keeps it, Matroska's to the millisecond: up to half a
      // millisecond before the true start, which at the timecode's own rate (29.97 fps: frame 1
      // at 33 ms, timecode frame 1 from 33.37 ms) is in the timecode frame before.
      constexpr std::int64_t kContainerRoundingNs = 500'000;
      row.push_back(',');
      append_timecode(row,
                      frame_after(timecode->first, std::llround(frame.media_time_s * 1e9) + kContainerRoundingNs,
                                  timecode->second),
                      timecode->second);
    }
    if (voice) voice->append(row, frame.media_time_s);
    row.push_back('\n');
    out.write(row.data(), static_cast<std::streamsize>(row.size()));
    ++rows;
    tracked_rows += result.tracked;
    ring.release();
    if (progress && rows % 10 == 0)
      fmt::print(stderr, "\r{} frames, {} tracked, {:.0f} frames/s ", rows, tracked_rows,
                 static_cast<double>(rows) / (ms_since(start) / 1000));
  }
  const double seconds = ms_since(start) / 1000;
  if (progress) fmt::print(stderr, "\r{} frames, {} tracked{:20}\n", rows, tracked_rows, "");
  // The frames that were processed are kept even where others could not be read (the errors
  // below); with none, the file stays as it was.
  if (!file) {
    out.flush();
    if (!out) throw CommandError("stdout: write failed", kExitIoError);
  } else if (rows > 0) {
    file->commit();
  }
  if (options.stats) print_stats(times, rows, seconds);

  const std::string input = options.input.string();
  if (decode_error)
    throw CommandError(fmt::format("{}: decoding failed after {} frames: {}", input, rows, *decode_error),
                       kExitDataError);
  damage.check(options.input, rows, independent);
  if (rows == 0) throw CommandError(fmt::format("{}: no frames to process", input), kExitDataError);
  if (tracked_rows == 0)
    throw CommandError(fmt::format("{}: no face found in any of the {} frames{}", input, rows,
                                   rotation == Rotation::k0
                                       ? " (from a camera mounted on its side, turn them upright: --rotate 90 or 270)"
                                       : ""),
                       kExitDataError);
}

}  // namespace

void add_process_command(CLI::App& app) {
  auto options = std::make_shared<ProcessOptions>();
  CLI::App* cmd = app.add_subcommand(
      "process", "Landmarks, 3DMM fit and mouth measures for every frame of a video, image or folder of images");
  cmd->add_option("INPUT", options->input, "video file, image, or folder of images")->required();
  cmd->add_option("--out", options->out, "CSV output file (default: stdout)");
  cmd->add_option("--config", options->config,
                  "the daemon's configuration file: [model] and [tracker] settings (default: the built-in defaults)");
  cmd->add_option("--model", options->model, "morphable model (.lpm; default: [model] file, else the built-in model)");
  cmd->add_option("--landmark-set", options->landmark_set,
                  "landmarks used by the fit (docs/method.md; default: [model] landmark_set, else F5)")
      ->check(CLI::IsMember(std::vector<std::string>(kLandmarkSetNames.begin(), kLandmarkSetNames.end())));
  cmd->add_option("--predictor", options->predictor,
                  fmt::format("landmark predictor (.lpp or dlib .dat; default: [tracker] predictor, else {})",
                              default_predictor_path().string()));
  cmd->add_flag("--include-landmarks", options->include_landmarks, "add the tracked landmarks x0..x67,y0..y67");
  cmd->add_flag("--stats", options->stats, "print per-stage latency and frames per second on stderr");
  cmd->add_option("--side", options->side, "side-camera recording of the same take: adds protrusion_side");
  cmd->add_option("--side-facing", options->side_facing,
                  "where the face looks in the side view; default: the --config's [side_camera] facing, else right")
      ->check(CLI::IsMember({"right", "left"}));
  cmd->add_option("--side-neutral-frames", options->side_neutral_frames,
                  "first side frames at rest that fix the reference line")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  cmd->add_option("--side-rotate", options->side_rotate,
                  "degrees clockwise that stand the side recording's frames upright; default: the --config's "
                  "[side_camera] rotation (enabled or not), else 0")
      ->check(CLI::IsMember({0, 90, 180, 270}));
  cmd->add_option("--timecode", options->timecode,
                  "timecode of the first frame (HH:MM:SS:FF): adds a timecode column, the recording's time from it");
  cmd->add_option("--timecode-fps", options->timecode_fps, "timecode rate: 24, 25, 29.97 (drop-frame) or 30")
      ->capture_default_str();
  cmd->add_option("--voice", options->voice,
                  "a voice model (.lpv, `lipdrive voice train`): adds open_voice, width_voice, protrusion_voice, "
                  "seal_voice from the clip's sound alone");
  cmd->add_option("--rotate", options->rotate,
                  "degrees clockwise that stand the frames upright (a camera mounted on its side); default: the "
                  "--config's [camera] rotation, else 0")
      ->check(CLI::IsMember({0, 90, 180, 270}));
  cmd->callback([options, cmd] {
    refuse_out_over_input(*cmd);
    run_process(*options);
  });
}

}  // namespace lipdrive
