// `lipdrive run`: the daemon. `lipdrive check-config`: validate its configuration file.
//
// Signals are blocked in every thread and taken on the main thread with sigtimedwait, so
// no handler runs in the middle of a frame: SIGHUP reloads the configuration, SIGUSR1
// re-captures the performer's neutral pose, SIGTERM and SIGINT stop cleanly (neutral pose on
// every output, threads joined) well within a second.
#include "firmware_app/command_error.hpp"
#include "firmware_app/commands.hpp"
#include "firmware_app/config.hpp"
#include "firmware_app/from_config.hpp"
#include "firmware_app/model_files.hpp"
#include "firmware_app/neutral_capture.hpp"
#include "firmware_app/outputs.hpp"
#include "firmware_app/performer_profile.hpp"
#include "firmware_app/pipeline.hpp"
#include "firmware_app/take_recorder.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <csignal>
#include <cstdio>
#include <memory>

namespace lipdrive {
namespace {

struct RunOptions {
  std::filesystem::path config;
  bool record = false;
  std::uint64_t frames = 0;
  bool stats = false;
};

/// The watchdog is fed at a quarter of systemd's timeout: late pings still arrive in time.
std::chrono::microseconds watchdog_interval() {
  std::uint64_t usec = 0;
  return sd_watchdog_enabled(0, &usec) > 0 ? std::chrono::microseconds(usec / 4) : std::chrono::microseconds(0);
}

/// Everything built from one configuration; replaced as a whole on reload.
struct Daemon {
  Config config;
  PerformerProfile profile;
  // Sinks and outputs before the pipeline: they must outlive it.
  std::unique_ptr<TakeRecorder> recorder;
  std::unique_ptr<NeutralCapture> neutral_capture;
  std::vector<std::unique_ptr<Output>> outputs;
  std::unique_ptr<Pipeline> pipeline;
  std::uint32_t calibrate_requests_seen = 0;
  bool model_mismatch = false;  // the performer's mouth and the model's are two classes apart
};

PerformerProfile load_performer(const Config& config) {
  if (config.performer.name.empty()) return PerformerProfile{};
  const PerformerProfile profile = load_profile(profile_path(config.performer.profiles_dir, config.performer.name));
  spdlog::info("performer {}: open [{:.3f}, {:.3f}], width [{:.3f}, {:.3f}], protrusion [{:.3f}, {:.3f}]",
               config.performer.name, profile.open.min, profile.open.max, profile.width.min, profile.width.max,
               profile.protrusion.min, profile.protrusion.max);
  return profile;
}

/// The daemon state bits outputs report (the pipeline adds tracking, fail-safe and the rest).
void update_daemon_status(Daemon& daemon) {
  std::uint16_t status = 0;
  if (daemon.profile.calibrated) status |= kStatusCalibrated;
  if (daemon.recorder->recording()) status |= kStatusRecording;
  if (daemon.model_mismatch) status |= kStatusModelMismatch;
  daemon.pipeline->control().daemon_status.store(status, std::memory_order_relaxed);
}

std::unique_ptr<Daemon> start_daemon(Config config, std::unique_ptr<FrameProcessor> processor,
                                     const RunOptions& options) {
  auto daemon = std::make_unique<Daemon>();
  PipelineSettings settings;
  settings.max_frames = options.frames;
  settings.watchdog_interval = watchdog_interval();
  settings.channels = config.channels;
  settings.safety = config.safety;
  daemon->pipeline = std::make_unique<Pipeline>(make_source(config), std::move(processor), settings);
  if (auto side = make_side_camera(config)) {
    spdlog::info("side camera: {}", side->describe());
    daemon->pipeline->set_side_camera(std::move(side));
  }
  daemon->recorder = std::make_unique<TakeRecorder>(daemon->pipeline->describe_source(),
                                                    std::chrono::milliseconds(config.recording.flush_interval_ms));
  daemon->pipeline->add_sink(*daemon->recorder);
  if (options.record || config.recording.start) daemon->recorder->start(take_file_name(config.recording.dir));
  daemon->neutral_capture = std::make_unique<NeutralCapture>(config.performer.neutral_frames);
  daemon->pipeline->add_sink(*daemon->neutral_capture);
  daemon->profile = load_performer(config);
  if (daemon->profile.face_indices) {
    const Compatibility check = model_compatibility(daemon->profile, load_model_file(config.model.file));
    daemon->model_mismatch = check.warn;
    if (check.warn)
      spdlog::warn("performer {}: vertical mouth height is {}, the model's {}: expect clearly worse lips (DESIGN.md 4.6)",
                   config.performer.name, index_class_name(check.performer.vertical_mouth_height),
                   index_class_name(check.model.vertical_mouth_height));
  }
  daemon->pipeline->set_profile(daemon->profile);
  daemon->outputs = make_outputs(config, daemon->pipeline->control());
  for (const auto& output : daemon->outputs) {
    daemon->pipeline->add_output(*output);
    spdlog::info("output: {}", output->describe());
  }
  daemon->config = std::move(config);
  update_daemon_status(*daemon);
  daemon->pipeline->start();
  spdlog::info("running: {}, model {}, landmark set {}", daemon->pipeline->describe_source(),
               daemon->config.model.file.string(), landmark_set_name(daemon->config.model.landmark_set));
  return daemon;
}

/// Fps over the last interval; latency over the whole run of the pipeline.
class StatusReporter {
 public:
  void report(const Pipeline& pipeline, const std::vector<std::unique_ptr<Output>>& outputs) {
    const PipelineStats s = pipeline.stats();
    const double seconds = s.seconds - last_seconds_;
    const double fps = seconds > 0 ? static_cast<double>(s.processed - last_processed_) / seconds : 0;
    last_seconds_ = s.seconds;
    last_processed_ = s.processed;
    FrameResult latest;
    pipeline.latest(latest);
    // While the camera is away the latest result is the last frame before it left.
    const std::string mouth =
        latest.tracked && s.connected
            ? fmt::format("mouth H/d {:.3f} W/d {:.3f} protrusion {:+.3f} ({}), drive open {:.2f} width {:.2f} "
                          "protrusion {:.2f}",
                          latest.measures.height_fit, latest.measures.width_fit,
                          latest.side_used ? latest.protrusion_side : latest.measures.protrusion_3d,
                          latest.side_used ? "side camera" : "3D fit", latest.signals[Signal::kOpen],
                          latest.signals[Signal::kWidth], latest.signals[Signal::kProtrusion])
                       : std::string("not tracked");
    std::string failing;
    for (const auto& output : outputs)
      if (!output->healthy()) failing += fmt::format(", {} failing", output->describe());
    const std::string line =
        fmt::format("{:.1f} fps, latency median {:.2f} ms p99 {:.2f} ms, {}, {}x{}, dropped {}{}{}", fps,
                    s.processed_median_ms, s.processed_p99_ms, mouth, latest.width, latest.height, s.dropped,
                    s.connected ? "" : ", camera disconnected", failing);
    spdlog::info("{}", line);
    sd_notifyf(0, "STATUS=%s", line.c_str());
  }

 private:
  double last_seconds_ = 0;
  std::uint64_t last_processed_ = 0;
};

void print_stats(const Daemon& daemon) {
  const PipelineStats s = daemon.pipeline->stats();
  fmt::print(stderr, "frames: captured {}, processed {}, tracked {}, dropped {}, corrupt {}, lost track {}, "
                     "disconnects {}\n",
             s.captured, s.processed, s.tracked, s.dropped, s.corrupt, s.lost_track, s.disconnects);
  fmt::print(stderr, "capture->processed latency: median {:.2f} ms, p99 {:.2f} ms\n", s.processed_median_ms,
             s.processed_p99_ms);
  fmt::print(stderr, "capture->output latency: median {:.2f} ms, p99 {:.2f} ms\n", s.output_median_ms,
             s.output_p99_ms);
  for (const auto& output : daemon.outputs) {
    if (const LatencyHistogram* wire = output->wire_latency(); wire && wire->count() > 0)
      fmt::print(stderr, "capture->wire latency, {}: median {:.2f} ms, p99 {:.2f} ms ({} frames)\n", output->describe(),
                 wire->quantile_ms(0.5), wire->quantile_ms(0.99), wire->count());
  }
  fmt::print(stderr, "fps: {:.1f} ({} frames in {:.2f} s)\n",
             s.seconds > 0 ? static_cast<double>(s.processed) / s.seconds : 0.0, s.processed, s.seconds);
}

/// A new daemon from the re-read file; the running one stays when the file, the model or the
/// predictor is wrong. The camera can only be opened once the old pipeline has let go of it:
/// if that fails, the previous configuration is started again.
void reload(std::unique_ptr<Daemon>& daemon, const RunOptions& options) {
  sd_notify(0, "RELOADING=1");
  Config config;
  std::unique_ptr<FrameProcessor> processor;
  try {
    config = load_config(options.config);
    processor = make_processor(config);
  } catch (const std::exception& e) {
    spdlog::error("reload failed, keeping the running configuration: {}", e.what());
    sd_notify(0, "READY=1");
    return;
  }
  spdlog::info("{}: reloaded; restarting the pipeline", options.config.string());
  Config previous = daemon->config;
  daemon.reset();
  try {
    spdlog::set_level(config.log_level);
    daemon = start_daemon(std::move(config), std::move(processor), options);
  } catch (const std::exception& e) {
    spdlog::error("the new configuration does not start, going back to the previous one: {}", e.what());
    spdlog::set_level(previous.log_level);
    daemon = start_daemon(previous, make_processor(previous), options);
  }
  sd_notify(0, "READY=1");
}

/// Calibrate and record commands from the outputs (Modbus, GPIO) and SIGUSR1; main thread.
void handle_commands(Daemon& daemon, bool calibrate_signal) {
  DriveControl& control = daemon.pipeline->control();
  const std::uint32_t requests = control.calibrate_requests.load(std::memory_order_relaxed);
  if (calibrate_signal || requests != daemon.calibrate_requests_seen) {
    daemon.calibrate_requests_seen = requests;
    daemon.pipeline->recalibrate_side();
    if (daemon.neutral_capture->arm())
      spdlog::info("calibrating: hold a neutral face for {} tracked frames", daemon.config.performer.neutral_frames);
  }
  if (daemon.neutral_capture->done()) {
    try {
      daemon.profile = recentre(daemon.profile, daemon.neutral_capture->samples());
      daemon.pipeline->set_profile(daemon.profile);
      spdlog::info("calibrated neutral: open {:.3f}, width {:.3f}, protrusion {:.3f}", daemon.profile.rest.open,
                   daemon.profile.rest.width, daemon.profile.rest.protrusion);
      const Config::Performer& performer = daemon.config.performer;
      if (!performer.name.empty())
        save_profile(profile_path(performer.profiles_dir, performer.name), performer.name, daemon.profile);
    } catch (const std::exception& e) {
      spdlog::error("calibration failed: {}", e.what());
    }
    daemon.neutral_capture->release();
  }
  const int record = control.recording_request.exchange(-1, std::memory_order_relaxed);
  if (record == 1 && !daemon.recorder->recording()) {
    daemon.recorder->start(take_file_name(daemon.config.recording.dir));
  } else if (record == 0 && daemon.recorder->recording()) {
    daemon.recorder->stop();
  }
  update_daemon_status(daemon);
}

int run_daemon(const RunOptions& options) {
  sigset_t signals;
  sigemptyset(&signals);
  for (int signal : {SIGHUP, SIGTERM, SIGINT, SIGUSR1}) sigaddset(&signals, signal);
  // Before any thread starts, so that every thread inherits the mask.
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  Config config = load_config(options.config);
  spdlog::set_level(config.log_level);
  auto processor = make_processor(config);
  std::unique_ptr<Daemon> daemon = start_daemon(std::move(config), std::move(processor), options);
  sd_notify(0, "READY=1");

  StatusReporter status;
  auto next_status =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(daemon->config.status.print_interval_ms);
  // Short enough to notice --frames and an ended recording promptly.
  const timespec poll{0, 50'000'000};
  for (;;) {
    const int signal = sigtimedwait(&signals, nullptr, &poll);
    if (signal == SIGTERM || signal == SIGINT) {
      spdlog::info("{}: stopping", strsignal(signal));
      break;
    }
    if (signal == SIGHUP) {
      reload(daemon, options);
      status = StatusReporter();  // a restarted pipeline counts from zero
    }
    handle_commands(*daemon, signal == SIGUSR1);
    if (daemon->pipeline->finished()) break;
    const int interval_ms = daemon->config.status.print_interval_ms;
    if (interval_ms > 0 && std::chrono::steady_clock::now() >= next_status) {
      status.report(*daemon->pipeline, daemon->outputs);
      next_status = std::chrono::steady_clock::now() + std::chrono::milliseconds(interval_ms);
    }
  }
  sd_notify(0, "STOPPING=1");
  daemon->pipeline->stop();
  if (options.stats) print_stats(*daemon);
  return daemon->pipeline->failed() ? kExitFailure : 0;
}

}  // namespace

void add_run_commands(CLI::App& app) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* run = app.add_subcommand("run", "Run the capture -> landmarks -> fit -> outputs daemon");
  run->add_option("--config", options->config, "configuration file (see config/lipdrive.toml)")->required();
  run->add_flag("--record", options->record, "record a take from the start (see [recording])");
  run->add_option("--frames", options->frames, "stop after this many processed frames (0 = run until stopped)");
  run->add_flag("--stats", options->stats, "print frame counts, latency and fps on stderr at exit");
  run->callback([options] {
    if (const int code = run_daemon(*options); code != 0)
      throw CommandError("the camera failed; see the messages above", code);
  });

  auto file = std::make_shared<std::filesystem::path>();
  CLI::App* check = app.add_subcommand("check-config", "Validate a configuration file without starting anything");
  check->add_option("FILE", *file, "configuration file")->required();
  check->callback([file] {
    load_config(*file);
    fmt::print("{}: ok\n", file->string());
  });
}

}  // namespace lipdrive
