// Reloading and stopping the daemon: the model and the predictor are read once and shared,
// a Modbus server polled flat out from several clients while the daemon is reloaded and
// stopped never reaches freed memory (the sanitizer lane runs this under AddressSanitizer),
// the systemd watchdog keeps being fed through reloads, and a reload moves no channel while a
// stop ends at the neutral pose.
#include "core/model_format.hpp"
#include "daemon_process.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/loaded_files.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/status_word.hpp"
#include "fixture_paths.hpp"
#include "osc_peers.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus/modbus-tcp.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <optional>
#include <thread>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using ::testing::HasSubstr;
using ::testing::Not;

const fs::path kPredictor = "/usr/share/dlib/shape_predictor_68_face_landmarks.dat";

/// How often `text` occurs in `log`.
int count(const std::string& log, const std::string& text) {
  int n = 0;
  for (auto at = log.find(text); at != std::string::npos; at = log.find(text, at + text.size())) ++n;
  return n;
}

/// Sends SIGHUP to a daemon that has started once; true when it is running again, reloaded.
bool reloaded_once(test::DaemonProcess& daemon) {
  daemon.signal(SIGHUP);
  const auto deadline = Clock::now() + 60s;
  while (count(daemon.log(), "running:") < 2 && Clock::now() < deadline) std::this_thread::sleep_for(5ms);
  return count(daemon.log(), "running:") == 2;
}

class ReloadTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("lipdrive_test_reload_{}_{}", ::getpid(),
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  /// The simulated camera at 60 fps, `more` tables, an `open` channel (with `channel_keys`) and a
  /// Modbus TCP server on `port`, written to the test's folder.
  fs::path modbus_server_config(int port, const std::string& more = "", const std::string& channel_keys = "") const {
    const fs::path config = dir_ / "lipdrive.toml";
    std::ofstream(config) << test::sim_camera_at_60_fps() << more
                          << fmt::format(R"([[channels]]
name = "open"
signal = "open"
{}[[outputs.modbus_server]]
transport = "tcp"
address = "127.0.0.1"
port = {}
)",
                                         channel_keys, port);
    return config;
  }
  fs::path dir_;
};

TEST_F(ReloadTest, AnUnchangedFileIsSharedAndAChangedOneReadAgain) {
  LoadedFiles files;
  const auto first = files.model(test::kModel);
  EXPECT_EQ(files.model(test::kModel), first) << "same file: the loaded model";
  EXPECT_EQ(files.reads(), 1);

  // The same bytes under another name, then rewritten in place: both are read.
  const fs::path copy = dir_ / "copy.lpm";
  fs::copy_file(test::kModel, copy);
  const auto copied = files.model(copy);
  EXPECT_NE(copied, first);
  EXPECT_EQ(files.reads(), 2);
  fs::last_write_time(copy, fs::last_write_time(copy) + 1s);
  EXPECT_NE(files.model(copy), copied) << "a rewritten file is read again";
  EXPECT_EQ(files.reads(), 3);

  // A file that went away is an error naming it, not the copy still in memory.
  fs::remove(copy);
  EXPECT_THROW(files.model(copy), CommandError);

  // A model with expression shapes is kept on its landmark vertices; its fingerprint is still
  // the whole file's (the one a profile's identity was calibrated against).
  const fs::path ict = fs::path(test::kModelDir) / "ict_face_light.lpm";
  const MorphableModel whole = load_model_file(ict);
  const auto kept = files.model(ict);
  EXPECT_LE(kept->num_vertices(), kNumLandmarks);
  EXPECT_EQ(kept->num_expressions(), whole.num_expressions());
  EXPECT_EQ(files.model_fingerprint(ict), identity_fingerprint(whole));
  EXPECT_EQ(files.model(test::kModel)->num_vertices(), load_model_file(test::kModel).num_vertices())
      << "a pose model is kept whole";
}

TEST_F(ReloadTest, ProcessorsOfTheSameConfigurationShareTheirFiles) {
  Config config;
  config.model.file = test::kModel;
  config.tracker.predictor = kPredictor;
  LoadedFiles files;
  const auto first = make_processor(config, files, PerformerProfile{});
  const auto second = make_processor(config, files, PerformerProfile{});
  EXPECT_EQ(files.reads(), 2) << "the model and the predictor once each";
}

/// Modbus TCP masters reading the first registers as fast as the server answers, connecting
/// again whenever the server goes away (as it does on every reload).
class PollingClients {
 public:
  PollingClients(int clients, int port) {
    for (int i = 0; i < clients; ++i)
      threads_.emplace_back([this, port] {
        while (!stop_) {
          modbus_t* master = modbus_new_tcp("127.0.0.1", port);
          modbus_set_response_timeout(master, 0, 200'000);
          if (modbus_connect(master) == 0) {
            std::uint16_t registers[8];
            while (!stop_ && modbus_read_input_registers(master, 0, 8, registers) == 8) ++reads_;
            // Holding registers too: the control registers the server reads from DriveControl.
            if (!stop_ && modbus_read_registers(master, 0, 3, registers) == 3) ++reads_;
          }
          modbus_close(master);
          modbus_free(master);
          std::this_thread::sleep_for(1ms);
        }
      });
  }
  ~PollingClients() { stop(); }
  void stop() {
    stop_ = true;
    for (auto& thread : threads_)
      if (thread.joinable()) thread.join();
  }
  std::uint64_t reads() const { return reads_; }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> reads_{0};
  std::vector<std::thread> threads_;
};

TEST_F(ReloadTest, ModbusPolledFlatOutThroughReloadsAndStop) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const int port = test::free_port();
  test::DaemonProcess daemon(modbus_server_config(port), dir_ / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:", 120s)) << daemon.log();

  PollingClients clients(4, port);
  constexpr int kReloads = 12;
  std::uint64_t reads_before = clients.reads();
  int polled_between = 0;  // reloads after which the clients were served again
  for (int reload = 1; reload <= kReloads; ++reload) {
    daemon.signal(SIGHUP);
    const auto deadline = Clock::now() + 60s;
    while (count(daemon.log(), "running:") < reload + 1 && Clock::now() < deadline && daemon.running())
      std::this_thread::sleep_for(5ms);
    ASSERT_TRUE(daemon.running()) << daemon.log();
    ASSERT_EQ(count(daemon.log(), "running:"), reload + 1) << "reload " << reload << "\n" << daemon.log();
    std::this_thread::sleep_for(150ms);
    polled_between += clients.reads() > reads_before;
    reads_before = clients.reads();
  }
  // Stopping while the clients still poll.
  daemon.signal(SIGTERM);
  const int exit_code = daemon.wait(10s);
  clients.stop();
  const std::string log = daemon.log();
  EXPECT_EQ(exit_code, 0) << log;
  EXPECT_THAT(log, Not(HasSubstr("Sanitizer"))) << log;
  EXPECT_EQ(polled_between, kReloads) << "the clients were served after every reload";
  EXPECT_GT(clients.reads(), 1000u);
  RecordProperty("modbus_reads", static_cast<int>(clients.reads()));
  std::printf("%d reloads and a stop under 4 clients polling: %llu reads answered\n", kReloads,
              static_cast<unsigned long long>(clients.reads()));
}

TEST_F(ReloadTest, WhatTheOperatorSetOutlivesAReload) {
  // The drive switched off, an override on the open channel, a take being recorded and the
  // neutral captured for a performer without a profile file: after SIGHUP all of it holds.
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const int port = test::free_port();
  test::DaemonProcess daemon(
      modbus_server_config(port, fmt::format("[recording]\ndir = \"{}\"\n", (dir_ / "takes").string())),
      dir_ / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:", 120s)) << daemon.log();
  modbus_t* master = modbus_new_tcp("127.0.0.1", port);
  ASSERT_NE(master, nullptr);
  ASSERT_EQ(modbus_connect(master), 0) << modbus_strerror(errno);
  const auto status = [&] {
    std::uint16_t word = 0;
    return modbus_read_input_registers(master, 0, 1, &word) == 1 ? word : std::uint16_t{0};
  };
  const auto wait_for_status = [&](std::uint16_t bits, bool set) {
    const auto deadline = Clock::now() + 30s;
    while (((status() & bits) == bits) != set && Clock::now() < deadline) std::this_thread::sleep_for(20ms);
    return ((status() & bits) == bits) == set;
  };
  constexpr std::uint16_t kCalibrated = 1 << 1, kRecording = 1 << 4, kEnabled = 1 << 5;
  ASSERT_EQ(modbus_write_register(master, 0, 0), 1);    // output enable off
  ASSERT_EQ(modbus_write_register(master, 16, 700), 1);  // override channel 0
  ASSERT_EQ(modbus_write_register(master, 2, 1), 1);    // record
  daemon.signal(SIGUSR1);                                // capture the neutral
  ASSERT_TRUE(wait_for_status(kRecording | kCalibrated, true)) << daemon.log();
  ASSERT_TRUE(wait_for_status(kEnabled, false));
  modbus_close(master);

  ASSERT_TRUE(reloaded_once(daemon)) << daemon.log();
  ASSERT_EQ(modbus_connect(master), 0) << modbus_strerror(errno);
  std::uint16_t holding[17] = {};
  ASSERT_EQ(modbus_read_registers(master, 0, 17, holding), 17);
  EXPECT_EQ(holding[0], 0) << "the drive stays off";
  EXPECT_EQ(holding[16], 700) << "the override stays on its channel";
  EXPECT_TRUE(wait_for_status(kRecording, true)) << "the take goes on";
  EXPECT_TRUE(wait_for_status(kCalibrated, true)) << "the neutral captured before the reload";
  EXPECT_FALSE(status() & kEnabled);
  EXPECT_THAT(daemon.log(), HasSubstr("the take goes on in"));
  modbus_close(master);
  modbus_free(master);
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(10s), 0) << daemon.log();
}

/// The first argument of the message at `address` in `bundle`, or NaN.
float osc_value(const test::OscCapture::Bundle& bundle, const std::string& address) {
  for (const auto& message : bundle.messages)
    if (message.address == address) return message.number;
  return std::nanf("");
}

// A reload hands the figure over where it is: an OSC output at 200 bundles a second sees a
// slew-limited channel overridden to 700 at that value through a reload, a storm of reloads and
// a configuration that does not start (the previous one started again), never the neutral pose
// in between (the old pipeline used to send it as it stopped) nor a climb back from it (the new
// one used to start from neutral); the new pipeline's frames start again at 1. A stop still
// ends with the neutral pose on the output.
TEST_F(ReloadTest, AReloadMovesNoChannelAndAStopEndsAtNeutral) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  test::OscCapture osc;
  const int port = test::free_port();
  const std::string osc_output =
      fmt::format("[[outputs.osc]]\nhost = \"127.0.0.1\"\nport = {}\nrate_hz = 200\n", osc.port());
  // Slew-limited: a drive that started again from neutral would take 0.7 s back to the value.
  const std::string slew = "max_slew_per_s = 1000\n";
  test::DaemonProcess daemon(modbus_server_config(port, osc_output, slew), dir_ / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:", 120s)) << daemon.log();
  modbus_t* master = modbus_new_tcp("127.0.0.1", port);
  ASSERT_NE(master, nullptr);
  ASSERT_EQ(modbus_connect(master), 0) << modbus_strerror(errno);
  constexpr float kHeld = 700, kNeutral = 0;
  ASSERT_EQ(modbus_write_register(master, 16, static_cast<std::uint16_t>(kHeld)), 1);  // override "open"
  modbus_close(master);
  modbus_free(master);
  // The index of the first bundle with the channel held, then of the first of the new pipeline.
  const auto first = [&](std::size_t from, auto&& is) -> std::optional<std::size_t> {
    const auto deadline = Clock::now() + 60s;
    for (;;) {
      const auto bundles = osc.bundles();
      for (std::size_t i = from; i < bundles.size(); ++i)
        if (is(bundles, i)) return i;
      if (Clock::now() > deadline) return std::nullopt;
      std::this_thread::sleep_for(10ms);
    }
  };
  const auto held_at =
      first(0, [&](const auto& bundles, std::size_t i) { return osc_value(bundles[i], "/lipdrive/open") == kHeld; });
  ASSERT_TRUE(held_at) << daemon.log();
  std::this_thread::sleep_for(500ms);  // the face tracked, the drive under way

  ASSERT_TRUE(reloaded_once(daemon)) << daemon.log();
  const auto restarted_at = first(*held_at + 1, [&](const auto& bundles, std::size_t i) {
    return osc_value(bundles[i], "/lipdrive/frame") < osc_value(bundles[i - 1], "/lipdrive/frame");
  });
  ASSERT_TRUE(restarted_at) << "no bundle of the new pipeline\n" << daemon.log();
  // The new pipeline's drive goes on for 20 bundles.
  ASSERT_TRUE(first(*restarted_at + 20, [](const auto&, std::size_t) { return true; })) << daemon.log();
  const auto bundles = osc.bundles();
  int off = 0, neutral = 0;  // bundles whose channel is not at the held value; of those, at neutral
  for (std::size_t i = *held_at; i < bundles.size(); ++i) {
    const float value = osc_value(bundles[i], "/lipdrive/open");
    if (value == kHeld) continue;
    neutral += value == kNeutral;
    if (++off <= 3)
      ADD_FAILURE() << "bundle " << i << " of " << bundles.size() << ", frame "
                    << osc_value(bundles[i], "/lipdrive/frame") << " (the new pipeline's first: bundle "
                    << *restarted_at << "): open " << value;
  }
  EXPECT_EQ(off, 0) << "bundles off the held value through the reload, " << neutral << " at the neutral pose";
  const auto gap = std::chrono::duration_cast<std::chrono::milliseconds>(bundles[*restarted_at].received -
                                                                         bundles[*restarted_at - 1].received);
  RecordProperty("reload_gap_ms", static_cast<int>(gap.count()));
  std::printf("reload: the last bundle of the old pipeline to the first of the new: %lld ms\n",
              static_cast<long long>(gap.count()));
  EXPECT_LT(gap, 10s);

  // A storm of reloads (sigtimedwait takes them one after the other, some together): still not
  // one bundle off the held value.
  const int started = count(daemon.log(), "running:");
  for (int i = 0; i < 20; ++i) {
    daemon.signal(SIGHUP);
    std::this_thread::sleep_for(10ms);
  }
  const auto storm_deadline = Clock::now() + 60s;
  while (count(daemon.log(), "reloaded; restarting the pipeline") < 2 && Clock::now() < storm_deadline)
    std::this_thread::sleep_for(10ms);
  std::this_thread::sleep_for(1s);
  ASSERT_TRUE(first(osc.bundles().size() + 20, [](const auto&, std::size_t) { return true; })) << daemon.log();
  const auto after_storm = osc.bundles();
  off = 0;
  for (std::size_t i = bundles.size(); i < after_storm.size(); ++i)
    off += osc_value(after_storm[i], "/lipdrive/open") != kHeld;
  const int storm = count(daemon.log(), "running:") - started;
  EXPECT_EQ(off, 0) << "bundles off the held value through " << storm << " more reloads";
  std::printf("20 SIGHUPs: %d reloads, %d bundles off the held value\n", storm, off);
  ASSERT_TRUE(daemon.running()) << daemon.log();

  // A configuration that does not start (a GPIO chip this machine does not have, which the
  // daemon stops on): the previous one, started again, carries on from the figure where it was
  // too.
  modbus_server_config(
      port, osc_output + "[outputs.gpio]\nenabled = true\nchip = \"gpiochip7\"\nenable_switch = \"GPIO24\"\n", slew);
  const std::size_t before_fallback = osc.bundles().size();
  daemon.signal(SIGHUP);
  const auto started_again = [&] {
    const std::string log = daemon.log();
    const auto failed = log.find("the new configuration does not start, going back to the previous one");
    return failed != std::string::npos && log.find("running:", failed) != std::string::npos;
  };
  const auto fallback_deadline = Clock::now() + 60s;
  while (!started_again() && Clock::now() < fallback_deadline) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(started_again()) << daemon.log();
  ASSERT_TRUE(first(osc.bundles().size() + 20, [](const auto&, std::size_t) { return true; })) << daemon.log();
  const auto after_fallback = osc.bundles();
  off = 0;
  for (std::size_t i = before_fallback; i < after_fallback.size(); ++i)
    off += osc_value(after_fallback[i], "/lipdrive/open") != kHeld;
  EXPECT_EQ(off, 0) << "bundles off the held value through the previous configuration started again";

  // A stop: the last bundle is the neutral pose, the fail-safe's.
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(10s), 0) << daemon.log();
  const auto last_is_neutral = [&] {
    const auto at_stop = osc.bundles();
    return osc_value(at_stop.back(), "/lipdrive/open") == kNeutral &&
           (static_cast<int>(osc_value(at_stop.back(), "/lipdrive/status")) & kStatusFailSafe) != 0;
  };
  const auto deadline = Clock::now() + 5s;  // the last datagram on its way to the receiver's thread
  while (!last_is_neutral() && Clock::now() < deadline) std::this_thread::sleep_for(10ms);
  EXPECT_TRUE(last_is_neutral()) << "the last bundle: open " << osc_value(osc.bundles().back(), "/lipdrive/open");
}

// A take started by --record (or [recording] start) and stopped by the operator stays stopped
// through a reload: the options are for the first start, the operator's state for the rest.
TEST_F(ReloadTest, ATakeTheOperatorStoppedIsNotStartedAgainByAReload) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const int port = test::free_port();
  const fs::path takes = dir_ / "takes";
  test::DaemonProcess daemon(
      modbus_server_config(port, fmt::format("[recording]\ndir = \"{}\"\nstart = true\n", takes.string())),
      dir_ / "stderr.txt", "--record");
  ASSERT_TRUE(daemon.wait_for_log("running:", 120s)) << daemon.log();
  modbus_t* master = modbus_new_tcp("127.0.0.1", port);
  ASSERT_NE(master, nullptr);
  ASSERT_EQ(modbus_connect(master), 0) << modbus_strerror(errno);
  constexpr std::uint16_t kRecording = 1 << 4;
  const auto recording = [&] {
    std::uint16_t word = 0;
    return modbus_read_input_registers(master, 0, 1, &word) == 1 && (word & kRecording) != 0;
  };
  const auto wait_for_recording = [&](bool set) {
    const auto deadline = Clock::now() + 30s;
    while (recording() != set && Clock::now() < deadline) std::this_thread::sleep_for(20ms);
    return recording() == set;
  };
  ASSERT_TRUE(wait_for_recording(true)) << daemon.log();
  ASSERT_EQ(modbus_write_register(master, 2, 0), 1);  // stop the take
  ASSERT_TRUE(wait_for_recording(false)) << daemon.log();
  modbus_close(master);

  ASSERT_TRUE(reloaded_once(daemon)) << daemon.log();
  ASSERT_EQ(modbus_connect(master), 0) << modbus_strerror(errno);
  std::this_thread::sleep_for(300ms);
  EXPECT_FALSE(recording()) << daemon.log();
  modbus_close(master);
  modbus_free(master);
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(10s), 0) << daemon.log();
  int files = 0;
  for (const auto& entry : fs::directory_iterator(takes)) files += entry.path().extension() == ".csv";
  EXPECT_EQ(files, 1) << "the first take only";
}

TEST_F(ReloadTest, TheWatchdogIsFedThroughReloads) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  // The unit's WatchdogSec=2; the daemon pings at a quarter of it.
  constexpr auto kWatchdog = 2000ms;
  // A second name for the predictor: a reload to it reads the file again.
  const fs::path other_predictor = dir_ / "other_predictor.dat";
  fs::create_symlink(kPredictor, other_predictor);
  const fs::path config = dir_ / "lipdrive.toml";
  const auto write_config = [&](const fs::path& predictor) {
    std::ofstream(config) << test::sim_camera_at_60_fps()
                          << fmt::format(
                                 "[tracker]\npredictor = \"{}\"\n[[channels]]\nname = \"open\"\nsignal = \"open\"\n",
                                 predictor.string());
  };
  write_config(kPredictor);
  test::NotifySocket notify(dir_ / "notify.sock");
  test::DaemonProcess daemon(
      config, dir_ / "stderr.txt", "",
      {notify.environment(), fmt::format("WATCHDOG_USEC={}", std::chrono::microseconds(kWatchdog).count())});
  ASSERT_TRUE(daemon.wait_for_log("running:", 120s)) << daemon.log();

  // Four reloads of the same file, then one to another predictor file, 1 s apart.
  constexpr int kReloads = 5;
  Clock::time_point next_reload = Clock::now() + 1s;
  test::WatchdogPings pings;
  int reloads = 0;
  const auto end = [&] { return reloads == kReloads && count(daemon.log(), "running:") == kReloads + 1; };
  // Each reload builds a processor (face detector, fitter, viseme poses) and the last reads
  // the 95 MB predictor: seconds each on a loaded machine.
  const auto deadline = Clock::now() + 300s;
  Clock::time_point finished{};
  while (Clock::now() < deadline && (finished == Clock::time_point{} || Clock::now() < finished + 1s)) {
    pings.see(notify.receive(10ms));
    if (reloads < kReloads && Clock::now() >= next_reload && count(daemon.log(), "running:") == reloads + 1) {
      if (reloads == kReloads - 1) write_config(other_predictor);
      daemon.signal(SIGHUP);
      ++reloads;
      next_reload = Clock::now() + 1s;
    }
    if (finished == Clock::time_point{} && end()) finished = Clock::now();
    ASSERT_TRUE(daemon.running()) << daemon.log();
  }
  ASSERT_TRUE(end()) << daemon.log();
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(5s), 0) << daemon.log();
  const std::string log = daemon.log();
  EXPECT_EQ(count(log, "reloaded; restarting the pipeline"), kReloads) << log;

  RecordProperty("watchdog_pings", pings.count());
  RecordProperty("worst_watchdog_gap_ms", static_cast<int>(pings.longest_gap().count()));
  std::printf(
      "%d reloads (the last to another predictor file): %d watchdog pings, longest gap %lld ms (timeout %lld ms)\n",
      kReloads, pings.count(), static_cast<long long>(pings.longest_gap().count()),
      static_cast<long long>(kWatchdog.count()));
  EXPECT_GT(pings.count(), 2 * kReloads);
  EXPECT_LT(pings.longest_gap(), kWatchdog) << "systemd would have killed the daemon during a reload";
}

}  // namespace
}  // namespace lipdrive
