// `lipdrive run` end to end on the simulated camera with real peers on its outputs: libmodbus
// masters read the register map over RTU (a socat pty pair) and TCP while the daemon runs, a
// reader on another pty pair decodes the framed serial protocol, and after SIGTERM the last
// thing on the serial line is the neutral pose; a Modbus port taken at start stops no other
// output.
#include "daemon_process.hpp"
#include "drivers/modbus_link.hpp"
#include "firmware_app/outputs/modbus_server_output.hpp"
#include "firmware_app/outputs/output.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <algorithm>
#include <cerrno>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using ::testing::HasSubstr;

using test::kClip;
constexpr int kWidthNeutral = 500;

/// The drive the tests run: `open`, and `width` whose neutral is kWidthNeutral; held 100 ms
/// when the face is lost, then eased to neutral over 200 ms.
std::string drive_of_open_and_width(int print_interval_ms) {
  return fmt::format(R"([status]
print_interval_ms = {}
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
)",
                     print_interval_ms, kWidthNeutral);
}

/// The "median X ms, p99 Y ms" figures of the --stats line that starts with `prefix`.
std::string stats_line(const std::string& log, const std::string& prefix) {
  const auto at = log.find(prefix);
  return at == std::string::npos ? "" : log.substr(at, log.find('\n', at) - at);
}

TEST(DaemonOutputs, ModbusAndSerialFollowTheMouthAndEndNeutral) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  const test::TempDir dir;
  const test::PtyPair line(dir.path() / "serial");
  test::PtyReader reader(line.b);
  const test::PtyPair rtu_line(dir.path() / "rtu");
  const int port = test::free_port();
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << test::sim_camera_at_60_fps()
                        << drive_of_open_and_width(0)
                        << fmt::format(R"([[outputs.modbus_server]]
port = {}
[[outputs.modbus_server]]
transport = "rtu"
device = "{}"
unit_id = 7
[[outputs.serial]]
mode = "framed"
device = "{}"
)",
                                       port, rtu_line.a.string(), line.a.string());
  test::DaemonProcess daemon(config, dir.path() / "stderr.txt", "--stats");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();

  // The same register map over RTU, from a master on the other end of the pty pair.
  const ModbusContext rtu(modbus_new_rtu(rtu_line.b.c_str(), 115200, 'N', 8, 1));
  ASSERT_EQ(modbus_connect(rtu.get()), 0) << modbus_strerror(errno);
  modbus_set_slave(rtu.get(), 7);
  modbus_set_response_timeout(rtu.get(), 1, 0);
  std::vector<std::uint16_t> rtu_heartbeats, rtu_opens;
  for (int poll = 0; poll < 40; ++poll) {
    std::array<std::uint16_t, modbus_map::kFirstChannel + 1> input{};
    ASSERT_EQ(modbus_read_input_registers(rtu.get(), 0, static_cast<int>(input.size()), input.data()),
              static_cast<int>(input.size()))
        << modbus_strerror(errno);
    rtu_heartbeats.push_back(input[modbus_map::kHeartbeat]);
    rtu_opens.push_back(input[modbus_map::kFirstChannel]);
    std::this_thread::sleep_for(25ms);
  }
  EXPECT_GT(std::ranges::count_if(rtu_heartbeats, [&](std::uint16_t h) { return h != rtu_heartbeats.front(); }), 30)
      << "RTU: the heartbeat increments";
  const auto [rtu_lowest, rtu_highest] = std::ranges::minmax(rtu_opens);
  EXPECT_GT(rtu_highest - rtu_lowest, 100) << "RTU: the open channel follows the talking mouth";

  // The register map over TCP while the daemon runs.
  const ModbusContext master(modbus_new_tcp("127.0.0.1", port));
  ASSERT_TRUE(test::eventually([&] { return modbus_connect(master.get()) == 0; }, 5s)) << modbus_strerror(errno);
  modbus_set_response_timeout(master.get(), 1, 0);
  constexpr int kRegisters = modbus_map::kFirstChannel + 2;
  std::vector<std::uint16_t> heartbeats, opens;
  bool tracking_seen = false;
  const auto until = std::chrono::steady_clock::now() + 3s;
  while (std::chrono::steady_clock::now() < until) {
    std::array<std::uint16_t, kRegisters> input{};
    ASSERT_EQ(modbus_read_input_registers(master.get(), 0, kRegisters, input.data()), kRegisters)
        << modbus_strerror(errno);
    heartbeats.push_back(input[modbus_map::kHeartbeat]);
    opens.push_back(input[modbus_map::kFirstChannel]);
    tracking_seen |= (input[modbus_map::kStatus] & kStatusTracking) != 0;
    EXPECT_EQ(input[modbus_map::kChannelCount], 2);
    reader.read_available();
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(tracking_seen);
  EXPECT_GT(std::ranges::count_if(heartbeats, [&](std::uint16_t h) { return h != heartbeats.front(); }), 100)
      << "the heartbeat increments";
  const auto [lowest, highest] = std::ranges::minmax(opens);
  EXPECT_GT(highest - lowest, 200) << "the open channel follows the talking mouth";

  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(1000ms), 0) << daemon.log();
  std::this_thread::sleep_for(100ms);
  const test::FrameStream stream = test::decode_frames(reader.read_available());
  ASSERT_GT(stream.frames.size(), 100u) << "framed frames over the pty";
  EXPECT_EQ(stream.skipped_bytes, 0u) << "every byte belongs to a frame with a valid CRC";
  int open_moves = 0;
  for (std::size_t i = 1; i < stream.frames.size(); ++i)
    open_moves += stream.frames[i].values[0] != stream.frames[i - 1].values[0];
  EXPECT_GT(open_moves, 50);
  const test::DecodedFrame& last = stream.frames.back();
  EXPECT_EQ(last.values, (std::vector<std::int16_t>{0, kWidthNeutral})) << "the last frame is the neutral pose";
  EXPECT_TRUE(last.status & kStatusFailSafe);
  EXPECT_FALSE(last.status & kStatusTracking);

  const std::string log = daemon.log();
  const std::string wire = stats_line(log, "capture->wire latency, serial");
  EXPECT_THAT(wire, HasSubstr("median")) << log;
  RecordProperty("serial_capture_to_wire", wire);
  RecordProperty("capture_to_processed", stats_line(log, "capture->processed latency"));
}

TEST(DaemonOutputs, AModbusPortTakenAtStartStopsNoOtherOutput) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  const test::TempDir dir;
  const test::PtyPair line(dir.path() / "serial");
  test::PtyReader reader(line.b);
  test::PortInUse taken;  // another program listens on the server's port
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << test::sim_camera_at_60_fps()
                        << drive_of_open_and_width(200)
                        << fmt::format(R"([[outputs.modbus_server]]
port = {}
[[outputs.serial]]
mode = "framed"
device = "{}"
)",
                                       taken.port(), line.a.string());
  test::DaemonProcess daemon(config, dir.path() / "stderr.txt");
  // Before the fix the daemon exited at once (1): wait for whichever comes first.
  ASSERT_TRUE(test::eventually(
      [&] { return daemon.log().find("running:") != std::string::npos || daemon.wait(0ms) != -1; }, 60s))
      << daemon.log();
  ASSERT_THAT(daemon.log(), HasSubstr("running:")) << "the daemon runs on";
  const std::string server = fmt::format("modbus server tcp 127.0.0.1:{}", taken.port());
  EXPECT_THAT(daemon.log(), HasSubstr(server + ": cannot listen: Address already in use; trying again with back-off"));
  EXPECT_TRUE(daemon.wait_for_log(server + " failing", 10s)) << "the status line says so\n" << daemon.log();

  // The serial output beside it is driven meanwhile.
  EXPECT_TRUE(test::eventually([&] { return test::decode_frames(reader.read_available()).frames.size() > 30; }, 10s))
      << "framed frames over the pty while the Modbus port is taken";

  // The port is freed: the server listens and serves without a restart.
  taken.release();
  const ModbusContext master(modbus_new_tcp("127.0.0.1", taken.port()));
  ASSERT_TRUE(test::eventually([&] { return modbus_connect(master.get()) == 0; }, 20s)) << daemon.log();
  modbus_set_response_timeout(master.get(), 1, 0);
  std::array<std::uint16_t, modbus_map::kFirstChannel + 2> input{};
  ASSERT_EQ(modbus_read_input_registers(master.get(), 0, static_cast<int>(input.size()), input.data()),
            static_cast<int>(input.size()))
      << modbus_strerror(errno);
  EXPECT_EQ(input[modbus_map::kChannelCount], 2);
  EXPECT_THAT(daemon.log(), HasSubstr(server + ": listening now"));

  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(3000ms), 0) << daemon.log();
  std::this_thread::sleep_for(100ms);
  const test::FrameStream stream = test::decode_frames(reader.read_available());
  ASSERT_GT(stream.frames.size(), 30u);
  EXPECT_EQ(stream.frames.back().values, (std::vector<std::int16_t>{0, kWidthNeutral}))
      << "the last frame is the neutral pose";
}

}  // namespace
}  // namespace lipdrive
