// The daemon `lipdrive run` holds: everything one configuration describes (the pipeline with
// its cameras, the outputs, the take recorder, the performer's profile), built and started
// together, replaced as a whole when the configuration is reloaded; and the monitor page.
//
// Thread model: the main thread makes every call. Every part is declared after what its
// threads use, so the members' own destruction order is the safe one: the monitor's threads are
// joined first (they read the pipeline, the outputs and the preview feed, and write the drive
// control), then the pipeline's (they use the feed, the outputs, the recorder, the voice room
// and the drive control), then the outputs and their threads go (the Modbus server writes the
// drive control), the recorder, the voice room's thread is joined (its simulated microphone
// reads the replay clock), the takes' sound (both push into it), and the drive control and the
// replay clock last. A constructor that
// throws half-way unwinds in the same order.
#pragma once

#include "firmware_app/config/config.hpp"
#include "firmware_app/config/loaded_files.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/daemon/osc_control.hpp"
#include "firmware_app/daemon/pipeline.hpp"
#include "firmware_app/daemon/preview_feed.hpp"
#include "firmware_app/daemon/take_recorder.hpp"
#include "firmware_app/daemon/timecode_source.hpp"
#include "firmware_app/daemon/voice_room.hpp"
#include "firmware_app/outputs/output.hpp"
#include "sim/replay_clock.hpp"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace lipdrive {

/// What `lipdrive run` adds to the configuration.
struct DaemonOptions {
  bool record = false;                             // record a take from the start
  std::uint64_t max_frames = 0;                    // stop after this many processed frames; 0 = never
  std::chrono::microseconds watchdog_interval{0};  // sd_notify WATCHDOG=1 this often; 0 = off
  std::string monitor_token;  // the monitor's control token when [monitor] names none; "" = a new one
};

/// What the operator set on a running daemon, which a reload keeps: a drive switched off stays
/// off, an override stays on the channel of the same name, a take being recorded goes on (in
/// a new file).
struct OperatorState {
  bool outputs_enabled = true;
  std::vector<std::pair<std::string, double>> overrides;  // channel name, value in output units
  bool recording = false;
};

class Monitor;

class Daemon {
 public:
  /// Builds everything `config` describes around `processor` (made with `profile`, the
  /// performer's: load_performer) and starts it. Throws ConfigError or CommandError when
  /// something cannot be opened or loaded. `files` holds the model the performer's profile is
  /// checked against (it outlives the daemon).
  /// `carried` (a reload's: operator_state() of the daemon it replaces) is in force before the
  /// pipeline starts; with it, a take is recorded where one was (a take the operator stopped is
  /// not started again by --record or [recording] start, which are for the first start).
  /// `drive` (a reload's: channel_state() of the daemon it replaces, stopped where it is) is where
  /// the channels carry on from, by name; empty: every channel starts at its neutral.
  Daemon(Config config, PerformerProfile profile, std::unique_ptr<FrameProcessor> processor,
         const DaemonOptions& options, LoadedFiles& files, const std::optional<OperatorState>& carried = {},
         const ChannelBankState& drive = {});
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// Main thread, a few times a second: starts or stops a take when an output asked, saves a
  /// profile the pipeline re-centred.
  void poll();
  /// SIGUSR1: re-capture the performer's neutral pose, like the GPIO button and the Modbus
  /// calibrate register.
  void request_calibration() { control_.calibrate_requests.fetch_add(1); }
  /// The status line: on the log and to systemd (STATUS=).
  void report_status();
  /// --stats: frame counts and latencies on stderr.
  void print_stats() const;
  /// Finishes the frame in hand, sends the neutral pose on every output (a reload's stop,
  /// kWhereItIs: nothing more, the figure stays where it is), joins the pipeline's threads and
  /// asks the outputs' to finish (they are joined as the daemon is destroyed).
  void stop(Pipeline::Leave leave = Pipeline::Leave::kNeutral);
  /// Once stopped: where the drive stands, for the daemon a reload makes.
  ChannelBankState channel_state() const { return pipeline_->channel_state(); }

  PipelineStats stats() const { return pipeline_->stats(); }
  bool finished() const { return pipeline_->finished(); }
  bool failed() const { return pipeline_->failed(); }
  const Config& config() const { return config_; }
  /// The performer's profile as last loaded or saved.
  const PerformerProfile& profile() const { return profile_; }
  /// What the operator set (enable, overrides, recording), for the daemon a reload makes.
  OperatorState operator_state() const;

 private:
  /// [monitor]: the page; a port or address that cannot be listened on is logged and the
  /// daemon runs on without it.
  void start_monitor(const std::string& fallback_token, bool model_mismatch);

  Config config_;
  PerformerProfile profile_;
  ReplayClock replay_clock_;  // the simulated camera's and the simulated microphone's timeline
  DriveControl
      control_;  // written by the Modbus server's thread, the GPIO buttons and the OSC control, read by the pipeline
  std::unique_ptr<TimecodeSource> timecode_;  // read by the pipeline's processing thread
  std::unique_ptr<TakeSound> sound_;          // [voice]: the voice room's thread writes it, the recorder's reads it
  std::unique_ptr<VoiceRoom> voice_;          // [voice]: read by the pipeline's threads
  std::unique_ptr<TakeRecorder> recorder_;
  std::unique_ptr<OscControl> osc_control_;       // its thread writes control_
  std::vector<std::unique_ptr<Output>> outputs_;  // their threads use control_
  std::unique_ptr<PreviewFeed> preview_;          // [monitor]: the processing thread writes it
  std::unique_ptr<Pipeline> pipeline_;            // its threads use all of the above
  std::unique_ptr<Monitor> monitor_;              // [monitor]: its threads read all of the above
  std::uint32_t saved_profile_version_ = 0;
  // The status line: fps over the last interval.
  double last_status_seconds_ = 0;
  std::uint64_t last_status_processed_ = 0;
};

/// SIGHUP: a new daemon from the re-read file. The running one stays when the file, the model
/// or the predictor is wrong; the camera can only be opened once the old pipeline has let go
/// of it, so if the new one does not start, the previous configuration is started again. The
/// new processor is built while the old pipeline still runs (and feeds the watchdog), from
/// `files`: a model or predictor whose file did not change is shared, not read again. The old
/// pipeline stops with the figure where it is, and the new one's channels (or the previous
/// configuration's, started again) carry on from there: no neutral pose in between.
void reload(std::unique_ptr<Daemon>& daemon, const std::filesystem::path& file, const DaemonOptions& options,
            LoadedFiles& files);

}  // namespace lipdrive
