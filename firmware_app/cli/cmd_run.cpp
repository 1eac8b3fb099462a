// `lipdrive run`: the daemon (daemon/daemon.hpp) under systemd.
//
// Signals are blocked in every thread and taken on the main thread with sigtimedwait, so
// no handler runs in the middle of a frame: SIGHUP reloads the configuration, SIGUSR1
// re-captures the performer's neutral pose, SIGTERM and SIGINT stop cleanly (neutral pose on
// every output, threads joined) well within a second.
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/daemon/daemon.hpp"
#include "firmware_app/monitor/monitor.hpp"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <chrono>
#include <csignal>
#include <cstring>
#include <memory>

namespace lipdrive {
namespace {

struct RunOptions {
  std::filesystem::path config;
  DaemonOptions daemon;
  bool stats = false;
};

/// The watchdog is fed at a quarter of systemd's timeout: late pings still arrive in time.
std::chrono::microseconds watchdog_interval() {
  std::uint64_t usec = 0;
  return sd_watchdog_enabled(0, &usec) > 0 ? std::chrono::microseconds(usec / 4) : std::chrono::microseconds(0);
}

int run_daemon(RunOptions options) {
  sigset_t signals;
  sigemptyset(&signals);
  for (int signal : {SIGHUP, SIGTERM, SIGINT, SIGUSR1}) sigaddset(&signals, signal);
  // Before any thread starts, so that every thread inherits the mask.
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  options.daemon.watchdog_interval = watchdog_interval();
  // One control token for the process, so that the monitor's link stays valid across reloads.
  options.daemon.monitor_token = new_control_token();
  Config config = load_config(options.config);
  spdlog::set_level(config.log_level);
  // The predictor and the model, loaded once for the process and shared by every reload.
  LoadedFiles files;
  PerformerProfile profile = load_performer(config);
  auto processor = make_processor(config, files, profile);
  auto daemon =
      std::make_unique<Daemon>(std::move(config), std::move(profile), std::move(processor), options.daemon, files);
  sd_notify(0, "READY=1");

  auto next_status =
      std::chrono::steady_clock::now() + std::chrono::milliseconds(daemon->config().status.print_interval_ms);
  // Short enough to notice --frames, an ended recording and a record request promptly.
  const timespec poll{0, 50'000'000};
  for (;;) {
    const int signal = sigtimedwait(&signals, nullptr, &poll);
    if (signal == SIGTERM || signal == SIGINT) {
      spdlog::info("{}: stopping", strsignal(signal));
      break;
    }
    if (signal == SIGHUP) reload(daemon, options.config, options.daemon, files);
    if (signal == SIGUSR1) daemon->request_calibration();
    daemon->poll();
    if (daemon->finished()) break;
    const int interval_ms = daemon->config().status.print_interval_ms;
    if (interval_ms > 0 && std::chrono::steady_clock::now() >= next_status) {
      daemon->report_status();
      next_status = std::chrono::steady_clock::now() + std::chrono::milliseconds(interval_ms);
    }
  }
  sd_notify(0, "STOPPING=1");
  daemon->stop();
  if (options.stats) daemon->print_stats();
  return daemon->failed() ? kExitFailure : 0;
}

}  // namespace

void add_run_command(CLI::App& app) {
  auto options = std::make_shared<RunOptions>();
  CLI::App* run = app.add_subcommand("run", "Run the capture -> landmarks -> fit -> outputs daemon");
  run->add_option("--config", options->config, "configuration file (see config/lipdrive.toml)")->required();
  run->add_flag("--record", options->daemon.record, "record a take from the start (see [recording])");
  run->add_option("--frames", options->daemon.max_frames,
                  "stop after this many processed frames (0 = run until stopped)")
      // CLI11 reads -1 into the unsigned count as 2^64 - 1, a count never reached.
      ->check(CLI::Validator(
          [](std::string& value) { return value.starts_with('-') ? "must not be negative" : std::string(); },
          "NONNEGATIVE"));
  run->add_flag("--stats", options->stats, "print frame counts, latency and fps on stderr at exit");
  run->callback([options] {
    if (const int code = run_daemon(*options); code != 0)
      throw CommandError("the camera failed; see the messages above", code);
  });
}

}  // namespace lipdrive
