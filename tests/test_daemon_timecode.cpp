// `lipdrive run` on the simulated camera with a timecode source: LTC generated at 25 fps
// (sim/ltc_generator.hpp) stamps every take row with the frame the encoder was playing when
// the camera frame was captured, the take's first line names the first row's timecode, the
// Modbus map carries it; the system clock at 29.97 drop-frame counts up across a take; LTC
// absent or garbled is a status-line warning.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "core/timecode.hpp"
#include "daemon_process.hpp"
#include "drivers/modbus_link.hpp"
#include "firmware_app/outputs/modbus_registers.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <modbus/modbus.h>

#include <algorithm>
#include <cerrno>
#include <sstream>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

struct Take {
  std::string first_line;
  std::vector<std::int64_t> capture_ns;
  std::vector<std::string> timecodes;  // "" when the row is not stamped
};

/// The one take in `dir`.
Take read_take(const fs::path& dir) {
  Take take;
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) files.push_back(entry.path());
  EXPECT_EQ(files.size(), 1u);
  if (files.empty()) return take;
  std::ifstream in(files.front());
  std::getline(in, take.first_line);
  std::string header;
  std::getline(in, header);
  EXPECT_TRUE(header.ends_with(",drive,capture_time_ns,timecode")) << header;
  for (std::string line; std::getline(in, line);) {
    const auto last = line.rfind(','), before = line.rfind(',', last - 1);
    take.capture_ns.push_back(std::stoll(line.substr(before + 1, last - before - 1)));
    take.timecodes.push_back(line.substr(last + 1));
  }
  return take;
}

std::string config_with(const std::string& timecode, const fs::path& takes, int modbus_port) {
  return test::sim_camera_at_60_fps() + fmt::format(R"([status]
print_interval_ms = 200
[recording]
dir = "{}"
start = true
[[channels]]
name = "open"
signal = "open"
[[outputs.modbus_server]]
port = {}
[timecode]
{}
)",
                                                    takes.string(), modbus_port, timecode);
}

TEST(DaemonTimecode, LtcStampsEveryTakeRowWithTheEncodersFrame) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const test::TempDir dir;
  const int port = test::free_port();
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << config_with("source = \"ltc\"\nfps = 25\nsim_start = \"09:59:58:00\"", dir.path() / "takes",
                                       port);
  test::DaemonProcess daemon(config, dir.path() / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
  std::this_thread::sleep_for(1000ms);
  // The Modbus map: hours · 256 + minutes, seconds · 256 + frames, valid, 25.00 fps.
  const ModbusContext master(modbus_new_tcp("127.0.0.1", port));
  ASSERT_TRUE(test::eventually([&] { return modbus_connect(master.get()) == 0; }, 5s)) << modbus_strerror(errno);
  std::array<std::uint16_t, 4> registers{};
  ASSERT_EQ(modbus_read_input_registers(master.get(), modbus_map::kTimecodeHoursMinutes, 4, registers.data()), 4);
  EXPECT_EQ(registers[2], 1) << "valid, not drop-frame";
  EXPECT_EQ(registers[3], 2500);
  const int hours = registers[0] >> 8, minutes = registers[0] & 0xFF, seconds = registers[1] >> 8;
  EXPECT_TRUE((hours == 9 && minutes == 59 && seconds >= 58) || (hours == 10 && minutes == 0 && seconds <= 2))
      << hours << ":" << minutes << ":" << seconds;
  std::this_thread::sleep_for(1500ms);  // past 10:00:00:00
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(2000ms), 0) << daemon.log();
  EXPECT_EQ(daemon.log().find("no LTC"), std::string::npos) << daemon.log();
  EXPECT_EQ(daemon.log().find("LTC garbled"), std::string::npos) << daemon.log();

  const Take take = read_take(dir.path() / "takes");
  ASSERT_GT(take.timecodes.size(), 50u);
  // Rows before the decoder locked on (two frames) are not stamped; all others are.
  const auto first = std::ranges::find_if(take.timecodes, [](const std::string& t) { return !t.empty(); });
  ASSERT_NE(first, take.timecodes.end());
  const std::size_t begin = static_cast<std::size_t>(first - take.timecodes.begin());
  EXPECT_LT(begin, 20u) << "stamped within a third of a second";
  // The take's first line names its first row's timecode: none while LTC was not locked yet.
  EXPECT_EQ(take.first_line, "# timecode_start " + (begin == 0 ? *first : std::string("none")) + " at 25 fps");
  // One phase for every row: frame f covers [phase + (f - f0) · 40 ms, phase + (f - f0 + 1) · 40 ms).
  const auto frame_of = [](const std::string& text) {
    const auto label = parse_timecode(text);
    return label ? frame_from_timecode(*label, TimecodeRate::k25).value_or(-1) : -1;
  };
  const std::int32_t f0 = frame_of(*first);
  double phase_low = -1e18, phase_high = 1e18;
  int stamped = 0;
  bool crossed = false;
  for (std::size_t i = begin; i < take.timecodes.size(); ++i) {
    const std::int32_t f = frame_of(take.timecodes[i]);
    ASSERT_GE(f, 0) << "row " << i << ": '" << take.timecodes[i] << "'";
    const double t = static_cast<double>(take.capture_ns[i]);
    phase_low = std::max(phase_low, t - (f - f0 + 1) * 40e6);
    phase_high = std::min(phase_high, t - (f - f0) * 40e6);
    crossed |= take.timecodes[i] == "10:00:00:00";
    ++stamped;
  }
  // libltc places a frame's start to within a few samples: 0.2 ms of slack.
  EXPECT_LT(phase_low, phase_high + 0.2e6) << "the rows' timecodes follow the encoder's frames, one phase for all "
                                           << (phase_low - phase_high) / 1e6 << " ms";
  EXPECT_TRUE(crossed);
  RecordProperty("ltc_rows_stamped",
                 fmt::format("{} of {} (the first {} before lock-on)", stamped, take.timecodes.size(), begin));
}

TEST(DaemonTimecode, SystemClockAtDropFrameCountsUpAcrossATake) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const test::TempDir dir;
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << config_with("source = \"clock\"\nfps = 29.97", dir.path() / "takes", test::free_port());
  test::DaemonProcess daemon(config, dir.path() / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
  std::this_thread::sleep_for(2000ms);
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(2000ms), 0) << daemon.log();
  const Take take = read_take(dir.path() / "takes");
  ASSERT_GT(take.timecodes.size(), 60u);
  std::int32_t previous = -1;
  std::int64_t previous_ns = 0;
  for (std::size_t i = 0; i < take.timecodes.size(); ++i) {
    const std::string& text = take.timecodes[i];
    ASSERT_EQ(text.size(), 11u);
    EXPECT_EQ(text[8], ';') << "drop-frame notation";
    const auto label = parse_timecode(text);
    ASSERT_TRUE(label);
    const std::int32_t frame = frame_from_timecode(*label, TimecodeRate::k29_97DropFrame).value_or(-1);
    ASSERT_GE(frame, 0) << text;
    if (previous >= 0) {
      EXPECT_GE(frame, previous) << text << " after " << format_frame(previous, TimecodeRate::k29_97DropFrame).view();
      // As many frames as the capture times are apart (rows skip frames the pipeline dropped).
      const double expected = static_cast<double>(take.capture_ns[i] - previous_ns) * 30000 / 1001 / 1e9;
      EXPECT_NEAR(frame - previous, expected, 1.0) << text;
    }
    previous = frame;
    previous_ns = take.capture_ns[i];
  }
  EXPECT_EQ(take.first_line, "# timecode_start " + take.timecodes.front() + " at 29.97 fps");
}

TEST(DaemonTimecode, AbsentOrGarbledLtcIsAStatusLineWarning) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  for (const auto& [keys, warning] :
       {std::pair<std::string, std::string>{"source = \"ltc\"\nsim_signal = \"noise\"", "no LTC on sim:"},
        {"source = \"ltc\"\nfps = 30\nsim_fps = 29.97", "LTC garbled on sim:"}}) {
    const test::TempDir dir;
    const fs::path config = dir.path() / "lipdrive.toml";
    std::ofstream(config) << config_with(keys, dir.path() / "takes", test::free_port());
    test::DaemonProcess daemon(config, dir.path() / "stderr.txt");
    ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
    EXPECT_TRUE(daemon.wait_for_log(warning, 5s)) << daemon.log();
    daemon.signal(SIGTERM);
    ASSERT_EQ(daemon.wait(2000ms), 0) << daemon.log();
    const Take take = read_take(dir.path() / "takes");
    EXPECT_TRUE(std::ranges::all_of(take.timecodes, [](const std::string& t) { return t.empty(); }))
        << "nothing stamped";
    EXPECT_EQ(take.first_line,
              "# timecode_start none at " + std::string(keys.find("30") != std::string::npos ? "30" : "25") + " fps");
  }
}

TEST(DaemonTimecode, LtcFromASoundCardThatIsAbsentLeavesFramesUnstampedAndCheckConfigNamesIt) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const test::TempDir dir;
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << config_with("source = \"ltc\"\nltc_input = \"alsa\"\ndevice = \"lipdrive_no_such_device\"",
                                       dir.path() / "takes", test::free_port());
  const test::CommandRun check = test::run_command(fmt::format("{} check-config {}", test::kLipdrive, config.string()));
  EXPECT_EQ(check.exit_code, 78) << check.output;
  EXPECT_NE(check.output.find("key timecode.device: alsa:lipdrive_no_such_device: cannot open the capture device"),
            std::string::npos)
      << check.output;

  test::DaemonProcess daemon(config, dir.path() / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
  EXPECT_NE(daemon.log().find("LTC input alsa:lipdrive_no_such_device: cannot open the capture device"),
            std::string::npos)
      << daemon.log();
  EXPECT_TRUE(daemon.wait_for_log("LTC input alsa:lipdrive_no_such_device lost", 5s)) << daemon.log();
  std::this_thread::sleep_for(500ms);
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(2000ms), 0) << daemon.log();
  const Take take = read_take(dir.path() / "takes");
  EXPECT_GT(take.timecodes.size(), 5u) << "the video runs on";
  EXPECT_TRUE(std::ranges::all_of(take.timecodes, [](const std::string& t) { return t.empty(); }));
}

}  // namespace
}  // namespace lipdrive
