// `lipdrive run` on the simulated camera with an OSC output to a liblo server in the test and
// the OSC control input: every drive frame arrives as one time-tagged bundle with the
// documented addresses (docs/osc.md), the remote commands take effect (a take named by slate
// and take, output enable, calibrate), and the capture -> received latency of the bundles.
#include "core/arkit.hpp"
#include "core/osc_addresses.hpp"
#include "core/statistics.hpp"
#include "daemon_process.hpp"
#include "firmware_app/daemon/status_word.hpp"
#include "fixture_paths.hpp"
#include "osc_peers.hpp"
#include "serial_peers.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <lo/lo.h>

#include <algorithm>
#include <cmath>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

/// Nanoseconds since the Unix epoch of an OSC (NTP) time tag.
std::int64_t unix_ns(lo_timetag tag) {
  constexpr std::int64_t kNtpToUnix = 2'208'988'800;
  return (static_cast<std::int64_t>(tag.sec) - kNtpToUnix) * 1'000'000'000 +
         static_cast<std::int64_t>((static_cast<std::uint64_t>(tag.frac) * 1'000'000'000) >> 32);
}

std::int64_t unix_ns(std::chrono::system_clock::time_point t) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count();
}

TEST(DaemonOsc, EveryDriveFrameIsOneBundleAndRemoteCommandsTakeEffect) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const test::TempDir dir;
  test::OscCapture capture;
  const int control_port = test::free_port(SOCK_DGRAM);
  const fs::path takes = dir.path() / "takes";
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << test::sim_camera_at_60_fps()
                        << fmt::format(R"([status]
print_interval_ms = 250
[recording]
dir = "{}"
[[channels]]
name = "open"
signal = "open"
[[channels]]
name = "width"
signal = "width"
[[channels]]
name = "seal"
signal = "seal"
[[outputs.osc]]
host = "localhost"
port = {}
[osc_control]
enabled = true
port = {}
)",
                                       takes.string(), capture.port(), control_port);
  test::DaemonProcess daemon(config, dir.path() / "stderr.txt", "--stats");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
  std::this_thread::sleep_for(3s);

  // Every bundle: the documented addresses in the documented order and types; the ARKit
  // weights under Apple's 52 names in Apple's order.
  std::vector<std::pair<std::string, std::string>> expected = {
      {"/lipdrive/frame", "i"},      {"/lipdrive/status", "i"},          {"/lipdrive/open", "f"},
      {"/lipdrive/width", "f"},      {"/lipdrive/seal", "f"},            {"/found", "i"},
      {"/gesture/mouth/width", "f"}, {"/gesture/mouth/height", "f"},     {"/gesture/jaw", "f"}};
  for (const std::string_view name : kArkitNames) expected.emplace_back(fmt::format("/{}", name), "f");
  ASSERT_EQ(expected[9 + 17].first, "/jawOpen");
  ASSERT_EQ(expected.back().first, "/tongueOut");
  auto bundles = capture.bundles();
  ASSERT_GT(bundles.size(), 120u) << daemon.log();
  EXPECT_TRUE(capture.loose_messages().empty()) << "everything travels in bundles";
  std::vector<double> latency_ms;
  std::vector<int> counters;
  bool found = false;
  float highest_jaw_open = 0;
  for (const auto& bundle : bundles) {
    ASSERT_EQ(bundle.messages.size(), expected.size()) << [&] {
      std::string addresses;
      for (const auto& m : bundle.messages) addresses += m.address + " ";
      return addresses;
    }();
    for (std::size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(bundle.messages[i].address, expected[i].first);
      EXPECT_EQ(bundle.messages[i].types, expected[i].second) << expected[i].first;
    }
    counters.push_back(static_cast<int>(bundle.messages[0].number));
    found |= bundle.messages[5].number == 1;
    highest_jaw_open = std::max(highest_jaw_open, bundle.messages[9 + 17].number);
    latency_ms.push_back(static_cast<double>(unix_ns(bundle.received) - unix_ns(bundle.time_tag)) / 1e6);
  }
  EXPECT_TRUE(found) << "/found 1 while the face is tracked";
  EXPECT_GT(highest_jaw_open, 0.3f) << "jawOpen follows the talking mouth";
  // One bundle per drive frame: the counters of consecutive bundles step by one.
  const std::size_t steps = counters.size() - 1;
  std::size_t consecutive = 0;
  for (std::size_t i = 1; i < counters.size(); ++i) consecutive += counters[i] == counters[i - 1] + 1;
  EXPECT_GE(static_cast<double>(consecutive), 0.98 * static_cast<double>(steps))
      << consecutive << " of " << steps << " bundles follow their predecessor's frame";
  RecordProperty("osc_consecutive_bundles", fmt::format("{} of {}", consecutive, steps));
  // The time tag is the capture time: a bundle arrives after it, and soon.
  const double median = quantile(latency_ms, 0.5), p99 = quantile(latency_ms, 0.99);
  EXPECT_GT(quantile(latency_ms, 0.0), -1.0) << "a time tag after the bundle arrived";
  EXPECT_LT(median, 50.0);
  const std::string figures = fmt::format("capture->OSC received: median {:.2f} ms, p99 {:.2f} ms ({} bundles)", median,
                                          p99, latency_ms.size());
  RecordProperty("osc_capture_to_received", figures);
  std::cerr << figures << "\n";

  // Remote commands, as Live Link Face sends them.
  const std::string port = std::to_string(control_port);
  lo_address to = lo_address_new("127.0.0.1", port.c_str());
  const auto status_now = [&] {
    const std::size_t seen = capture.bundles().size();
    EXPECT_TRUE(test::eventually([&] { return capture.bundles().size() > seen + 2; }, 2s));
    return static_cast<int>(capture.bundles().back().messages[1].number);
  };
  ASSERT_GT(lo_send(to, "/RecordStart", "si", "Scene 12", 3), 0);
  const fs::path take = takes / "Scene_12_3.csv";
  EXPECT_TRUE(test::eventually([&] { return fs::exists(take); }, 3s)) << daemon.log();
  EXPECT_TRUE(test::eventually([&] { return (status_now() & kStatusRecording) != 0; }, 3s));
  std::this_thread::sleep_for(500ms);
  ASSERT_GT(lo_send(to, "/RecordStop", ""), 0);
  EXPECT_TRUE(test::eventually([&] { return (status_now() & kStatusRecording) == 0; }, 3s));
  std::ifstream rows(take);
  const auto lines = std::count(std::istreambuf_iterator<char>(rows), std::istreambuf_iterator<char>(), '\n');
  EXPECT_GT(lines, 15) << "half a second of rows at 60 fps";
  // The next take under the same slate counts up.
  ASSERT_GT(lo_send(to, "/RecordStart", ""), 0);
  EXPECT_TRUE(test::eventually([&] { return fs::exists(takes / "Scene_12_4.csv"); }, 3s)) << daemon.log();
  ASSERT_GT(lo_send(to, "/RecordStop", ""), 0);

  ASSERT_GT(lo_send(to, "/lipdrive/output_enable", "i", 0), 0);
  EXPECT_TRUE(test::eventually([&] { return (status_now() & kStatusOutputsEnabled) == 0; }, 3s));
  EXPECT_TRUE(daemon.wait_for_log(", outputs disabled", 3s)) << "the status line says why the figure rests";
  // A command whose argument is not what it takes is refused with the reason and does nothing:
  // a NaN does not switch the drive on, as `NaN != 0` would.
  ASSERT_GT(lo_send(to, "/lipdrive/output_enable", "f", std::nanf("")), 0);
  ASSERT_GT(lo_send(to, "/lipdrive/output_enable", "s", "1"), 0);
  ASSERT_GT(lo_send(to, "/Take", "f", 2.5f), 0);
  ASSERT_GT(lo_send(to, "/lipdrive/no_such_command", "i", 1), 0);
  EXPECT_TRUE(daemon.wait_for_log("/lipdrive/no_such_command ,i refused: no such command", 3s)) << daemon.log();
  EXPECT_NE(daemon.log().find("/lipdrive/output_enable ,f refused: it takes one number"), std::string::npos);
  EXPECT_NE(daemon.log().find("/lipdrive/output_enable ,s refused"), std::string::npos);
  EXPECT_NE(daemon.log().find("/Take ,f refused: it takes one take number"), std::string::npos);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(status_now() & kStatusOutputsEnabled, 0) << "a refused command acted";
  ASSERT_GT(lo_send(to, "/lipdrive/output_enable", "i", 1), 0);
  EXPECT_TRUE(test::eventually([&] { return (status_now() & kStatusOutputsEnabled) != 0; }, 3s));
  ASSERT_GT(lo_send(to, "/lipdrive/calibrate", ""), 0);
  EXPECT_TRUE(daemon.wait_for_log("calibrating", 3s)) << daemon.log();

  // A sender gone wrong: 3,000 junk datagrams and 3,000 commands as fast as they go. The log
  // keeps to ten lines a second of each, then says how many it held back.
  const auto lines_with = [&](const std::string& text) {
    const std::string log = daemon.log();
    int n = 0;
    for (auto at = log.find(text); at != std::string::npos; at = log.find(text, at + 1)) ++n;
    return n;
  };
  const int enables_before = lines_with("/lipdrive/output_enable");
  const int junk = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in control{};
  control.sin_family = AF_INET;
  control.sin_port = htons(static_cast<std::uint16_t>(control_port));
  control.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  const auto flood_start = std::chrono::steady_clock::now();
  for (int i = 0; i < 3000; ++i) {
    ::sendto(junk, "not osc", 7, 0, reinterpret_cast<const sockaddr*>(&control), sizeof control);
    lo_send(to, "/lipdrive/output_enable", "i", 1);
    if (i % 100 == 99) std::this_thread::sleep_for(1ms);  // within the socket's buffer
  }
  ::close(junk);
  const double flood_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - flood_start).count() + 1.0;
  std::this_thread::sleep_for(1100ms);
  ASSERT_GT(lo_send(to, "/lipdrive/output_enable", "i", 1), 0);  // in a new second: logged with the count
  EXPECT_TRUE(daemon.wait_for_log("more held back", 3s)) << daemon.log();
  const int most = static_cast<int>(10 * (flood_s + 2));
  EXPECT_LE(lines_with("malformed OSC datagram"), most);
  EXPECT_LE(lines_with("/lipdrive/output_enable") - enables_before, most);
  EXPECT_GE(lines_with("malformed OSC datagram"), 1);
  lo_address_free(to);

  // A burst just before the stop: what was held back in the last second is counted at the stop,
  // since no later line carries it.
  std::this_thread::sleep_for(1100ms);
  const int burst = ::socket(AF_INET, SOCK_DGRAM, 0);
  for (int i = 0; i < 50; ++i)
    ::sendto(burst, "not osc", 7, 0, reinterpret_cast<const sockaddr*>(&control), sizeof control);
  ::close(burst);
  std::this_thread::sleep_for(200ms);
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(2000ms), 0) << daemon.log();
  EXPECT_NE(daemon.log().find("refused datagrams and commands: 40 more held back in its last second"),
            std::string::npos)
      << daemon.log();
  const std::string log = daemon.log();
  const auto at = log.find("capture->wire latency, osc");
  ASSERT_NE(at, std::string::npos) << log;
  RecordProperty("osc_capture_to_sent", log.substr(at, log.find('\n', at) - at));
  std::cerr << log.substr(at, log.find('\n', at) - at) << "\n";
}

// The OSC control's port held by another program at start: the daemon drives the figure all the
// same (it stopped with exit 78, which the unit does not restart), says why, and takes commands
// once the port is free.
TEST(DaemonOsc, AControlPortTakenAtStartIsBoundOnceFreeAndTheFigureIsDrivenMeanwhile) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const test::TempDir dir;
  test::OscCapture capture;
  test::PortInUse holder(SOCK_DGRAM);
  const int control_port = holder.port();
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << test::sim_camera_at_60_fps()
                        << fmt::format(
                               "[[channels]]\nname = \"open\"\nsignal = \"open\"\n"
                               "[[outputs.osc]]\nhost = \"127.0.0.1\"\nport = {}\n"
                               "[osc_control]\nenabled = true\nport = {}\n",
                               capture.port(), control_port);
  test::DaemonProcess daemon(config, dir.path() / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
  EXPECT_NE(daemon.log().find(fmt::format("osc control udp 127.0.0.1:{}: udp 127.0.0.1:{}: cannot bind: Address "
                                          "already in use; trying again",
                                          control_port, control_port)),
            std::string::npos)
      << daemon.log();
  EXPECT_TRUE(test::eventually([&] { return capture.bundles().size() > 30; }, 5s)) << "the figure is driven";
  holder.release();
  EXPECT_TRUE(daemon.wait_for_log("bound; OSC control again", 5s)) << daemon.log();
  lo_address to = lo_address_new("127.0.0.1", std::to_string(control_port).c_str());
  ASSERT_GT(lo_send(to, "/lipdrive/output_enable", "i", 0), 0);
  lo_address_free(to);
  EXPECT_TRUE(test::eventually(
      [&] {
        const auto bundles = capture.bundles();
        return (static_cast<int>(bundles.back().messages[1].number) & kStatusOutputsEnabled) == 0;
      },
      3s))
      << daemon.log();
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(3000ms), 0) << daemon.log();
}

}  // namespace
}  // namespace lipdrive
