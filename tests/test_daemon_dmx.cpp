// `lipdrive run` on the simulated camera with a DMX output to a real olad (started by the
// test, tests/ola_peers.hpp): the universe olad holds follows the channel mapping (open
// 16-bit, width and seal 8-bit, exact values through Modbus overrides), at most 44 frames a second;
// olad killed and restarted mid-run: the output reports itself failing, comes back within 2 s,
// and the serial output beside it keeps its latency; after SIGTERM the universe holds the
// neutral pose.
#include "core/statistics.hpp"
#include "daemon_process.hpp"
#include "drivers/modbus_link.hpp"
#include "drivers/thread_scheduling.hpp"
#include "firmware_app/outputs/modbus_registers.hpp"
#include "fixture_paths.hpp"
#include "ola_peers.hpp"
#include "serial_peers.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <optional>
#include <set>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr unsigned kUniverse = 3;
// The daemon's frame path and the serial reader under SCHED_FIFO ([scheduling], as a show runs
// it: docs/packaging.md): without it, olad's start-up on the two cores added up to 12 ms to the
// serial output's p99 (README).
constexpr int kRealtimePriority = 20;
constexpr int kWidthNeutral = 500;

std::int64_t now_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(Clock::now().time_since_epoch()).count();
}

/// Serial bytes as they arrive, read every millisecond on a thread of its own, with the time
/// each read returned them. The reading thread runs under SCHED_FIFO like the daemon's frame
/// path (below), so that olad's start-up, which takes both cores for a moment, delays neither
/// the output nor its measurement.
class SerialArrivals {
 public:
  explicit SerialArrivals(const std::filesystem::path& device) : reader_(device), thread_([this] { run(); }) {
    scheduling_ = schedule_thread(thread_, "serial-reader", kRealtimePriority);
  }
  /// Why SCHED_FIFO was refused ("" when granted).
  const std::string& scheduling() const { return scheduling_; }
  ~SerialArrivals() { stop(); }
  /// Stops reading; afterwards bytes() and arrivals() may be used.
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  const test::Bytes& bytes() { return reader_.read_available(); }
  /// (CLOCK_MONOTONIC µs, bytes so far), one entry per read that brought bytes.
  const std::vector<std::pair<std::int64_t, std::size_t>>& arrivals() const { return arrivals_; }

 private:
  void run() {
    while (!stop_) {
      const std::size_t size = reader_.read_available().size();
      if (arrivals_.empty() || size != arrivals_.back().second) arrivals_.emplace_back(now_us(), size);
      std::this_thread::sleep_for(1ms);
    }
  }
  test::PtyReader reader_;
  std::string scheduling_;
  std::vector<std::pair<std::int64_t, std::size_t>> arrivals_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

TEST(DaemonDmx, UniverseFollowsTheMappingSurvivesAnOladRestartAndEndsNeutral) {
  if (!test::OladProcess::installed()) GTEST_SKIP() << "olad is not installed (Debian package ola)";
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const test::TempDir dir;
  test::OladProcess olad(test::free_port());
  auto watcher = std::make_unique<test::UniverseWatcher>(olad.rpc_port(), kUniverse);
  const test::PtyPair line(dir.path() / "serial");
  SerialArrivals serial(line.b);
  const int modbus_port = test::free_port();
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << test::sim_camera_at_60_fps()
                        << fmt::format(R"([scheduling]
realtime_priority = {}
[status]
print_interval_ms = 100
[safety]
hold_ms = 100
ease_ms = 200
[[channels]]
name = "open"
signal = "open"
[[channels]]
name = "width"
signal = "width"
neutral = {}
[[channels]]
name = "seal"
signal = "seal"
[[outputs.modbus_server]]
port = {}
[[outputs.serial]]
mode = "framed"
device = "{}"
[[outputs.dmx]]
universe = {}
start_address = 10
rpc_port = {}
[[outputs.dmx.channels]]
name = "open"
bits = 16
[[outputs.dmx.channels]]
name = "width"
[[outputs.dmx.channels]]
name = "seal"
)",
                                       kRealtimePriority, kWidthNeutral, modbus_port, line.a.string(), kUniverse,
                                       olad.rpc_port());
  test::DaemonProcess daemon(config, dir.path() / "stderr.txt", "--stats");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();

  std::this_thread::sleep_for(2500ms);

  // What olad passes on: 13 slots (1..9 unused), open coarse + fine at 10, 11, width at 12, seal at 13.
  auto updates = watcher->updates();
  ASSERT_GT(updates.size(), 40u) << daemon.log();
  std::set<int> opens;
  for (const auto& update : updates) {
    ASSERT_EQ(update.slots.size(), 13u);
    EXPECT_TRUE(std::all_of(update.slots.begin(), update.slots.begin() + 9, [](std::uint8_t s) { return s == 0; }));
    opens.insert(update.slots[9] << 8 | update.slots[10]);
  }
  EXPECT_GT(opens.size(), 20u) << "the 16-bit open channel follows the talking mouth";
  // The rate cap: frames in the last whole second.
  const auto last = updates.back().time;
  const auto in_last_second =
      std::ranges::count_if(updates, [&](const auto& update) { return update.time > last - 1s; });
  EXPECT_LE(in_last_second, 45) << "DMX carries at most 44 frames a second";
  EXPECT_GE(in_last_second, 30) << "the universe is refreshed continuously";
  RecordProperty("dmx_frames_per_second", static_cast<int>(in_last_second));

  // Exact levels: overrides put known values on the three channels.
  {
    const ModbusContext master(modbus_new_tcp("127.0.0.1", modbus_port));
    ASSERT_EQ(modbus_connect(master.get()), 0) << modbus_strerror(errno);
    const std::uint16_t overrides[] = {333, 250, 600};
    ASSERT_EQ(modbus_write_registers(master.get(), modbus_map::kFirstOverride, 3, overrides), 3);
    // 333 / 1000 · 65535 = 21823.2 -> 0x553F; 250 / 1000 · 255 = 63.75 -> 64; 600 -> 153.
    const auto overridden = [&] {
      const auto all = watcher->updates();
      return !all.empty() && all.back().slots[9] == 0x55 && all.back().slots[10] == 0x3F &&
             all.back().slots[11] == 64 && all.back().slots[12] == 153;
    };
    EXPECT_TRUE(test::eventually(overridden, 2s)) << "the overridden values, coarse, fine and 8-bit";
    const std::uint16_t none[] = {modbus_map::kNoOverride, modbus_map::kNoOverride, modbus_map::kNoOverride};
    ASSERT_EQ(modbus_write_registers(master.get(), modbus_map::kFirstOverride, 3, none), 3);
  }

  // olad goes away for a second: the output reports itself failing, the serial line goes on.
  std::this_thread::sleep_for(500ms);
  const std::int64_t outage_begin_us = now_us();
  olad.kill();
  watcher.reset();
  const std::size_t log_before = daemon.log().size();
  EXPECT_TRUE(test::eventually([&] { return daemon.log().find("failing", log_before) != std::string::npos; }, 1000ms))
      << "the status line names the failing output\n"
      << daemon.log();
  std::this_thread::sleep_for(500ms);
  olad.start();
  const auto restarted = Clock::now();
  watcher = std::make_unique<test::UniverseWatcher>(olad.rpc_port(), kUniverse);
  std::optional<Clock::time_point> recovered;
  const auto until = restarted + 3s;
  while (Clock::now() < until && !recovered) {
    if (const auto all = watcher->updates(); !all.empty()) recovered = all.front().time;
    std::this_thread::sleep_for(1ms);
  }
  const std::int64_t outage_end_us = now_us();
  ASSERT_TRUE(recovered) << "no DMX after olad came back\n" << daemon.log();
  const double recovery_ms = std::chrono::duration<double, std::milli>(*recovered - restarted).count();
  EXPECT_LT(recovery_ms, 2000) << "back within 2 s of olad listening again";
  RecordProperty("dmx_recovery_ms", fmt::format("{:.0f}", recovery_ms));
  std::this_thread::sleep_for(1000ms);

  daemon.signal(SIGTERM);
  const auto term = Clock::now();
  ASSERT_EQ(daemon.wait(5000ms), 0) << daemon.log();
  const double exit_ms = std::chrono::duration<double, std::milli>(Clock::now() - term).count();
  RecordProperty("exit_after_sigterm_ms", fmt::format("{:.0f}", exit_ms));
  std::cerr << "exit " << exit_ms << " ms after SIGTERM\n";
  // The last frame lipdrive sent, as olad passes it on (under load that takes a while; once
  // its source is gone olad may pass on an emptied universe, which is not a frame of ours).
  // open 0 -> 0x0000; width 500 / 1000 · 255 = 127.5 -> 128; seal 0.
  const auto last_sent = [&] {
    const auto all = watcher->updates();
    const auto last =
        std::ranges::find_if(all.rbegin(), all.rend(), [](const auto& u) { return u.slots.size() == 13; });
    return last == all.rend() ? test::Universe{} : last->slots;
  };
  EXPECT_TRUE(test::eventually(
      [&] {
        const test::Universe neutral = last_sent();
        return neutral.size() == 13 && neutral[9] == 0 && neutral[10] == 0 && neutral[11] == 128 && neutral[12] == 0;
      },
      2s))
      << "the last frame is the neutral pose";
  EXPECT_NE(daemon.log().find("sending again"), std::string::npos) << daemon.log();

  // The serial output beside it: compute -> read latency of each frame, outside the outage and
  // during it (frames are all the same size; frame k has arrived when (k + 1) · size bytes have).
  serial.stop();
  const test::FrameStream stream = test::decode_frames(serial.bytes());
  ASSERT_GT(stream.frames.size(), 200u);
  ASSERT_EQ(stream.skipped_bytes, 0u);
  const std::size_t frame_size = serial.bytes().size() / stream.frames.size();
  const auto& arrivals = serial.arrivals();
  std::vector<double> normal, outage;
  std::size_t next = 0;
  for (std::size_t k = 0; k + 1 < stream.frames.size(); ++k) {
    while (next < arrivals.size() && arrivals[next].second < (k + 1) * frame_size) ++next;
    if (next == 0 || next >= arrivals.size()) continue;
    // The reads are 1 ms apart: the frame arrived between the previous read and this one.
    const std::int64_t arrived_us = arrivals[next].first;
    const std::int64_t computed_us = static_cast<std::uint32_t>(stream.frames[k].time_us);
    const double latency_ms = static_cast<double>((arrived_us - computed_us) & 0xFFFF'FFFF) / 1000.0;
    if (latency_ms > 10'000) continue;  // before the reads started
    (arrived_us >= outage_begin_us && arrived_us <= outage_end_us ? outage : normal).push_back(latency_ms);
  }
  ASSERT_GT(outage.size(), 20u);
  ASSERT_GT(normal.size(), 100u);
  const std::string figures = fmt::format(
      "serial compute->read latency: olad up median {:.2f} ms p99 {:.2f} ms ({} frames); olad down or "
      "restarting median {:.2f} ms p95 {:.2f} ms max {:.2f} ms ({} frames)",
      quantile(normal, 0.5), quantile(normal, 0.99), normal.size(), quantile(outage, 0.5), quantile(outage, 0.95),
      quantile(outage, 1.0), outage.size());
  RecordProperty("serial_latency_during_olad_outage", figures);
  RecordProperty("serial_reader_scheduling", serial.scheduling().empty() ? "SCHED_FIFO" : serial.scheduling());
  std::cerr << figures << "\n";
  EXPECT_LT(quantile(outage, 0.5), quantile(normal, 0.5) + 2.0) << figures;
  // The outage holds some 40 frames, so their p99 is their single largest latency, which one
  // pause of a shared host fails (up to 26 ms: scripts/host-pauses.py; twice in local runs
  // beside builds, 11.5 and 14.0 ms against bounds of 10 and 12.4). Held instead: their p95 to
  // the bound, and every one of them under the DMX sender's first back-off (100 ms), which a
  // frame that waited on olad would take.
  EXPECT_LT(quantile(outage, 0.95), std::max(10.0, 2 * quantile(normal, 0.99))) << figures;
  EXPECT_LT(quantile(outage, 1.0), 100.0) << figures;
}

}  // namespace
}  // namespace lipdrive
