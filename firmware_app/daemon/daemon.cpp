#include "firmware_app/daemon/daemon.hpp"

#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "firmware_app/daemon/status_word.hpp"
#include "firmware_app/monitor/monitor.hpp"
#include "firmware_app/outputs/make_outputs.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <cmath>
#include <csignal>
#include <cstdio>

namespace lipdrive {
namespace {

/// The performer's mouth and the model's are two vertical-mouth-height classes apart
/// (docs/method.md 6): logged, and reported in the status word.
bool model_mismatch(const Config& config, const PerformerProfile& profile, LoadedFiles& files) {
  if (!profile.face_indices) return false;
  const Compatibility check = model_compatibility(profile, *files.model(config.model.file));
  if (check.warn)
    spdlog::warn(
        "performer {}: vertical mouth height is {}, the model's {}: expect clearly worse lips (docs/method.md 6)",
        config.performer.name, index_class_name(check.performer.vertical_mouth_height),
        index_class_name(check.model.vertical_mouth_height));
  return check.warn;
}

}  // namespace

Daemon::Daemon(Config config, PerformerProfile profile, std::unique_ptr<FrameProcessor> processor,
               const DaemonOptions& options, LoadedFiles& files, const std::optional<OperatorState>& carried,
               const ChannelBankState& drive)
    : config_(std::move(config)), profile_(std::move(profile)) {
  if (carried) {
    control_.outputs_enabled.store(carried->outputs_enabled);
    for (const auto& [name, value] : carried->overrides)
      if (const std::optional<int> channel = find_channel(config_.channels, name))
        control_.overrides[static_cast<std::size_t>(*channel)].store(value);
  }
  PipelineSettings settings;
  settings.max_frames = options.max_frames;
  settings.watchdog_interval = options.watchdog_interval;
  settings.channels = config_.channels;
  settings.safety = config_.safety;
  settings.neutral_frames = config_.performer.neutral_frames;
  settings.realtime_priority = config_.scheduling.realtime_priority;
  settings.cpu_latency_us = config_.scheduling.cpu_latency_us;
  settings.warm_ahead = std::chrono::microseconds(config_.scheduling.warm_ahead_us);
  settings.model_mismatch = model_mismatch(config_, profile_, files);
  settings.voice_crossfade = std::chrono::milliseconds(config_.voice.crossfade_ms);
  settings.voice_timeout = std::chrono::milliseconds(config_.voice.audio_timeout_ms);
  // The clip's sound keeps to the simulated camera's timeline.
  const bool sim_voice = config_.voice.enabled && config_.voice.input == Config::Voice::Input::kSim;
  std::unique_ptr<FrameSource> source = make_source(config_, sim_voice ? &replay_clock_ : nullptr);
  if (config_.voice.enabled) sound_ = std::make_unique<TakeSound>(config_.voice.alsa.sample_rate);
  voice_ = make_voice_room(config_, &replay_clock_, sound_.get());
  if (!voice_) sound_.reset();
  timecode_ = make_timecode(config_);
  recorder_ = std::make_unique<TakeRecorder>(
      source->describe(), std::chrono::milliseconds(config_.recording.flush_interval_ms),
      timecode_ ? std::optional<TimecodeRate>(timecode_->rate()) : std::nullopt, sound_.get());
  pipeline_ = std::make_unique<Pipeline>(std::move(source), std::move(processor), settings, control_);
  pipeline_->carry_on(drive);
  if (auto side = make_side_camera(config_)) {
    spdlog::info("side camera: {}", side->describe());
    pipeline_->set_side_camera(std::move(side));
  }
  pipeline_->set_recorder(*recorder_);
  if (timecode_) {
    pipeline_->set_timecode(*timecode_);
    spdlog::info("timecode: {}", timecode_->describe());
  }
  pipeline_->set_profile(profile_);
  if (voice_) pipeline_->set_voice(*voice_);
  outputs_ = make_outputs(config_, control_);
  for (const auto& output : outputs_) {
    pipeline_->add_output(*output);
    spdlog::info("output: {}", output->describe());
  }
  if (config_.osc_control.enabled) {
    try {
      osc_control_ = std::make_unique<OscControl>(config_.osc_control.address, config_.osc_control.port, control_);
    } catch (const UdpError& e) {
      // Resolved when the file was loaded; a name server that changed its mind since.
      fail_unresolved(fmt::format("{}: key osc_control.address", config_.file.string()), e);
    }
    spdlog::info("{}", osc_control_->describe());
  }
  if (config_.monitor.enabled) {
    preview_ = std::make_unique<PreviewFeed>(config_.monitor.preview_fps, config_.monitor.preview_size);
    pipeline_->set_preview(*preview_);
  }
  if (carried ? carried->recording : options.record || config_.recording.start) {
    const std::string take = take_file_name(config_.recording.dir);
    recorder_->start(take);
    if (carried) spdlog::info("the take goes on in {}", take);
  }
  pipeline_->start();
  spdlog::info("running: {}, model {}, landmark set {}, predictor {}", pipeline_->describe_source(),
               config_.model.file.string(), landmark_set_name(config_.model.landmark_set),
               config_.tracker.predictor.string());
  if (config_.monitor.enabled) start_monitor(options.monitor_token, settings.model_mismatch);
}

// Stopped here too for a daemon a reload replaces: its outputs finish together.
Daemon::~Daemon() { stop(); }

void Daemon::stop(Pipeline::Leave leave) {
  pipeline_->stop(leave);
  for (const auto& output : outputs_) output->request_stop();
}

void Daemon::start_monitor(const std::string& fallback_token, bool model_mismatch) {
  const Config::Monitor& settings = config_.monitor;
  std::vector<const Output*> outputs;
  for (const auto& output : outputs_) outputs.push_back(output.get());
  const std::string token = !settings.token.empty()   ? settings.token
                            : !fallback_token.empty() ? fallback_token
                                                      : new_control_token();
  monitor_ = std::make_unique<Monitor>(settings,
                                       MonitorSources{*pipeline_, control_, *preview_, std::move(outputs),
                                                      config_.channels, config_.performer.name, model_mismatch},
                                       token);
  if (!monitor_->start()) {
    monitor_.reset();
    return;
  }
  // The operator opens this link; a token from the configuration is not repeated in the log.
  if (settings.token.empty()) spdlog::info("monitor: control token {}: {}#token={}", token, monitor_->url(), token);
}

void Daemon::poll() {
  const int record = control_.recording_request.exchange(-1, std::memory_order_relaxed);
  if (record == 1 && !recorder_->recording()) {
    const std::optional<std::string> name = osc_control_ ? osc_control_->next_take_name() : std::nullopt;
    recorder_->start(take_file_name(config_.recording.dir, name.value_or("")));
  } else if (record == 0 && recorder_->recording()) {
    recorder_->stop();
  }
  PerformerProfile recentred;
  if (const std::uint32_t version = pipeline_->recentred_profile(recentred); version != saved_profile_version_) {
    saved_profile_version_ = version;
    profile_ = recentred;
    const Config::Performer& performer = config_.performer;
    if (performer.name.empty()) return;
    try {
      save_profile(profile_path(performer.profiles_dir, performer.name), performer.name, profile_);
    } catch (const std::exception& e) {
      spdlog::error("the re-centred profile was not saved: {}", e.what());
    }
  }
}

OperatorState Daemon::operator_state() const {
  OperatorState state;
  state.outputs_enabled = control_.outputs_enabled.load();
  for (std::size_t i = 0; i < config_.channels.size(); ++i)
    if (const double value = control_.overrides[i].load(); !std::isnan(value))
      state.overrides.emplace_back(config_.channels[i].name, value);
  state.recording = recorder_->recording();
  return state;
}

void Daemon::report_status() {
  const PipelineStats s = pipeline_->stats();
  const double seconds = s.seconds - last_status_seconds_;
  const double fps = seconds > 0 ? static_cast<double>(s.processed - last_status_processed_) / seconds : 0;
  last_status_seconds_ = s.seconds;
  last_status_processed_ = s.processed;
  FrameResult latest;
  pipeline_->latest(latest);
  // While the camera is away the latest result is the last frame before it left.
  const std::string mouth =
      latest.tracked && s.connected
          ? fmt::format(
                "mouth open H/d {:.3f} seal {:.2f} W/d {:.3f} protrusion {:+.3f} ({}), drive open {:.2f} "
                "width {:.2f} protrusion {:.2f}",
                latest.measures.open, latest.measures.seal, latest.measures.width_fit,
                latest.side_used ? latest.protrusion_side : latest.measures.protrusion_3d,
                latest.side_used ? "side camera" : "3D fit", latest.signals[Signal::kOpen],
                latest.signals[Signal::kWidth], latest.signals[Signal::kProtrusion])
          : std::string("not tracked");
  std::string warnings;
  for (const auto& output : outputs_)
    if (!output->healthy()) warnings += fmt::format(", {} failing", output->describe());
  if (timecode_)
    if (const std::string problem = timecode_->problem(); !problem.empty()) warnings += ", " + problem;
  if (voice_)
    if (const std::string problem = voice_->problem(); !problem.empty()) warnings += ", " + problem;
  DriveFrame drive;
  pipeline_->latest_drive(drive);
  if (drive.counter > 0 && !(drive.status & kStatusOutputsEnabled))
    warnings += control_.outputs_enabled.load() ? ", enable switch open" : ", outputs disabled";
  const std::string timecode =
      latest.timecode >= 0 && timecode_
          ? fmt::format(", timecode {}", format_frame(latest.timecode, timecode_->rate()).view())
          : std::string();
  // Before the first processed frame (a camera not there yet) there is no latency nor size.
  const std::string latency =
      std::isnan(s.processed_median_ms)
          ? std::string("latency n/a")
          : fmt::format("latency median {:.2f} ms p99 {:.2f} ms", s.processed_median_ms, s.processed_p99_ms);
  const std::string size = latest.width > 0 ? fmt::format(", {}x{}", latest.width, latest.height) : std::string();
  const std::string line = fmt::format("{:.1f} fps, {}, drive {}, {}{}, dropped {}{}{}{}", fps, latency,
                                       drive_source_name(status_source(drive.status)), mouth, size, s.dropped,
                                       timecode, s.connected ? "" : ", camera disconnected", warnings);
  spdlog::info("{}", line);
  sd_notifyf(0, "STATUS=%s", line.c_str());
}

void Daemon::print_stats() const {
  const PipelineStats s = pipeline_->stats();
  fmt::print(stderr,
             "frames: captured {}, processed {}, tracked {}, dropped {}, corrupt {}, lost track {}, "
             "disconnects {}, warmed ahead {}\n",
             s.captured, s.processed, s.tracked, s.dropped, s.corrupt, s.lost_track, s.disconnects, s.warmed);
  fmt::print(stderr, "capture->processed latency: median {:.2f} ms, p99 {:.2f} ms\n", s.processed_median_ms,
             s.processed_p99_ms);
  fmt::print(stderr,
             "capture->processed by stage (median / p99 ms, 0.05 ms bins): hand-off {:.2f} / {:.2f}, landmarks {:.2f} / {:.2f}, "
             "fit {:.2f} / {:.2f}, measures {:.2f} / {:.2f}\n",
             s.hand_off.median_ms, s.hand_off.p99_ms, s.landmarks.median_ms, s.landmarks.p99_ms, s.fit.median_ms,
             s.fit.p99_ms, s.measures.median_ms, s.measures.p99_ms);
  fmt::print(stderr, "capture->output latency: median {:.2f} ms, p99 {:.2f} ms\n", s.output_median_ms, s.output_p99_ms);
  for (const auto& output : outputs_) {
    if (const LatencyHistogram* wire = output->wire_latency(); wire && wire->count() > 0)
      fmt::print(stderr, "capture->wire latency, {}: median {:.2f} ms, p99 {:.2f} ms ({} frames)\n", output->describe(),
                 wire->quantile_ms(0.5), wire->quantile_ms(0.99), wire->count());
  }
  if (voice_)
    fmt::print(stderr,
               "sound block->output latency while the voice drives: median {:.2f} ms, p99 {:.2f} ms ({} drive frames; "
               "the model's look-ahead comes on top)\n",
               s.voice_median_ms, s.voice_p99_ms, s.voice_frames);
  fmt::print(stderr, "fps: {:.1f} ({} frames in {:.2f} s)\n",
             s.seconds > 0 ? static_cast<double>(s.processed) / s.seconds : 0.0, s.processed, s.seconds);
}

void reload(std::unique_ptr<Daemon>& daemon, const std::filesystem::path& file, const DaemonOptions& options,
            LoadedFiles& files) {
  sd_notify(0, "RELOADING=1");
  daemon->poll();  // a calibration that just finished is saved before the profile is read again
  Config config;
  PerformerProfile profile;
  std::unique_ptr<FrameProcessor> processor;
  try {
    config = load_config(file);
    // A performer without a name has no profile file: the running daemon's calibration is theirs.
    profile = config.performer.name.empty() && daemon->config().performer.name.empty() ? daemon->profile()
                                                                                         : load_performer(config);
    processor = make_processor(config, files, profile);
  } catch (const std::exception& e) {
    spdlog::error("reload failed, keeping the running configuration: {}", e.what());
    sd_notify(0, "READY=1");
    return;
  }
  // Asked to stop while the new processor was built (a predictor parsed on a slow board): the
  // running daemon stops, as it would have, instead of a new one starting first.
  sigset_t pending;
  sigpending(&pending);
  if (sigismember(&pending, SIGTERM) || sigismember(&pending, SIGINT)) return;
  spdlog::info("{}: reloaded; restarting the pipeline", file.string());
  Config previous = daemon->config();
  PerformerProfile previous_profile = daemon->profile();
  const OperatorState carried = daemon->operator_state();
  // No neutral pose in between: the figure stays where it is, and the new drive carries on
  // from there with its slew limits, hold and ease. So does the previous configuration's when
  // the new one does not start: the one that failed sent nothing.
  daemon->stop(Pipeline::Leave::kWhereItIs);
  const ChannelBankState drive = daemon->channel_state();
  daemon.reset();
  try {
    spdlog::set_level(config.log_level);
    daemon = std::make_unique<Daemon>(std::move(config), std::move(profile), std::move(processor), options, files,
                                      carried, drive);
  } catch (const std::exception& e) {
    spdlog::error("the new configuration does not start, going back to the previous one: {}", e.what());
    spdlog::set_level(previous.log_level);
    daemon = std::make_unique<Daemon>(previous, previous_profile, make_processor(previous, files, previous_profile),
                                      options, files, carried, drive);
  }
  sd_notify(0, "READY=1");
}

}  // namespace lipdrive
