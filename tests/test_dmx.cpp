// DMX512: the footprint (addresses, 8-bit and 16-bit coarse/fine levels, collisions) and the
// OLA client against a real olad started by the test, including olad going away and coming
// back.
#include "captured_log.hpp"
#include "core/dmx_footprint.hpp"
#include "daemon_process.hpp"
#include "drivers/ola_client.hpp"
#include "firmware_app/outputs/dmx_output.hpp"
#include "ola_peers.hpp"
#include "serial_peers.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <vector>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;

DmxSlotSpec slot(std::string name, int index, int address, bool sixteen_bit, double min = 0, double max = 1000) {
  return {.channel = std::move(name),
          .channel_index = index,
          .address = address,
          .sixteen_bit = sixteen_bit,
          .range_min = min,
          .range_max = max};
}

TEST(DmxFootprint, LevelsSpanTheWholeDmxRange) {
  const DmxSlotSpec eight = slot("jaw", 0, 1, false), sixteen = slot("lip", 0, 1, true);
  EXPECT_EQ(dmx_level(eight, 0), 0);
  EXPECT_EQ(dmx_level(eight, 1000), 255);
  EXPECT_EQ(dmx_level(eight, 500), 128);  // 127.5 rounds up
  EXPECT_EQ(dmx_level(eight, -50), 0);
  EXPECT_EQ(dmx_level(eight, 5000), 255);
  EXPECT_EQ(dmx_level(sixteen, 0), 0);
  EXPECT_EQ(dmx_level(sixteen, 1000), 65535);
  EXPECT_EQ(dmx_level(sixteen, 250), 16384);  // 16383.75
  EXPECT_EQ(dmx_level(sixteen, std::nan("")), 0);
  // A reversed range: out_min is DMX 0 whichever way round the channel runs.
  const DmxSlotSpec reversed = slot("r", 0, 1, false, 2000, 1000);
  EXPECT_EQ(dmx_level(reversed, 2000), 0);
  EXPECT_EQ(dmx_level(reversed, 1000), 255);
}

TEST(DmxFootprint, EncodesCoarseThenFineAndLeavesOtherSlots) {
  const std::vector<DmxSlotSpec> footprint{slot("open", 0, 1, true), slot("width", 1, 3, false),
                                           slot("smile", 2, 511, true)};
  ASSERT_FALSE(check_footprint(footprint));
  std::array<std::uint8_t, kDmxUniverseSlots> universe{};
  universe[9] = 77;
  const std::array<double, 3> values{250, 1000, 750};
  encode_dmx(footprint, values, universe);
  EXPECT_EQ(universe[0], 0x40);  // 16384 = 0x4000
  EXPECT_EQ(universe[1], 0x00);
  EXPECT_EQ(universe[2], 255);
  EXPECT_EQ(universe[9], 77) << "slots outside the footprint are left alone";
  EXPECT_EQ(universe[510], 0xBF);  // round(0.75 * 65535) = 49151 = 0xBFFF
  EXPECT_EQ(universe[511], 0xFF);
}

TEST(DmxFootprint, RejectsAddressesOutsideTheUniverseAndCollisions) {
  const auto error = [](std::vector<DmxSlotSpec> footprint) { return check_footprint(footprint); };
  EXPECT_FALSE(error({slot("a", 0, 512, false)}));
  const auto zero = error({slot("a", 0, 0, false)});
  ASSERT_TRUE(zero);
  EXPECT_EQ(zero->index, 0u);
  EXPECT_NE(zero->reason.find("between 1 and 512"), std::string::npos) << zero->reason;
  const auto last = error({slot("a", 0, 1, false), slot("b", 1, 512, true)});
  ASSERT_TRUE(last);
  EXPECT_EQ(last->index, 1u);
  EXPECT_NE(last->reason.find("16-bit"), std::string::npos) << last->reason;
  // "b" at 2..3 overlaps the fine slot of "a" at 1..2.
  const auto overlap = error({slot("a", 0, 1, true), slot("b", 1, 2, true)});
  ASSERT_TRUE(overlap);
  EXPECT_EQ(overlap->index, 1u);
  EXPECT_EQ(overlap->reason, "channel \"b\" at address 2 collides with channel \"a\" (addresses 1..2) at address 2");
  EXPECT_TRUE(error({slot("a", 0, 1, false, 5, 5)})) << "an empty range cannot be scaled";
}

TEST(OlaDmxClient, NoOladMeansNoConnection) {
  OlaDmxClient client(test::free_port());
  EXPECT_FALSE(client.connect());
  EXPECT_FALSE(client.connected());
  const std::array<std::uint8_t, 3> slots{1, 2, 3};
  EXPECT_FALSE(client.send(1, slots, 100));
}

// The daemon's stop with olad gone: the neutral pose cannot go out, and the log says so (as it
// does for a Modbus slave that stopped answering) instead of nothing.
TEST(DmxOutput, ANeutralPoseThatCannotBeSentIsSaid) {
  DmxOutputOptions options;
  options.rpc_port = test::free_port();  // no olad there
  options.footprint = {DmxSlotSpec{.channel = "open", .channel_index = 0, .address = 1}};
  const testing::CapturedLog log;
  {
    DmxOutput output(options);
    DriveFrame frame;
    frame.channel_count = 1;
    frame.values[0] = 0.5;
    output.publish(frame);
    frame.counter = 1;
    output.publish(frame);
  }
  const auto warnings = log.messages(spdlog::level::warn);
  EXPECT_TRUE(std::ranges::any_of(warnings, [](const std::string& m) {
    return m.find("the neutral pose was not sent") != std::string::npos;
  })) << (warnings.empty() ? "no warning" : warnings.back());
}

TEST(OlaDmxClient, OladHoldsWhatWasSentAndTheClientNoticesARestart) {
  if (!test::OladProcess::installed()) GTEST_SKIP() << "olad is not installed (Debian package ola)";
  test::OladProcess olad(test::free_port());
  // olad keeps universes that something uses (a patched port, a registered client) and
  // drops data for others: the watcher is that user here.
  auto watcher = std::make_unique<test::UniverseWatcher>(olad.rpc_port(), 7);
  OlaDmxClient client(olad.rpc_port());
  ASSERT_TRUE(client.connect());
  std::array<std::uint8_t, kDmxUniverseSlots> universe{};
  universe[0] = 0x40;
  universe[1] = 0x01;
  universe[511] = 200;
  ASSERT_TRUE(test::eventually(
      [&] {
        EXPECT_TRUE(client.send(7, universe, 100));
        return !watcher->updates().empty();
      },
      3s));
  const test::Universe seen = watcher->updates().back().slots;
  ASSERT_EQ(seen.size(), static_cast<std::size_t>(kDmxUniverseSlots));
  EXPECT_EQ(seen[0], 0x40);
  EXPECT_EQ(seen[1], 0x01);
  EXPECT_EQ(seen[2], 0);
  EXPECT_EQ(seen[511], 200);
  EXPECT_EQ(test::fetch_universe(olad.rpc_port(), 7), seen);

  // olad vanishes: a send fails within a few attempts and the client reports it.
  olad.kill();
  watcher.reset();
  EXPECT_TRUE(test::eventually([&] { return !client.send(7, universe, 100); }, 2s));
  EXPECT_FALSE(client.connected());
  EXPECT_FALSE(client.connect());

  // olad is back: a reconnect and a send restore the universe.
  olad.start();
  watcher = std::make_unique<test::UniverseWatcher>(olad.rpc_port(), 7);
  ASSERT_TRUE(client.connect());
  universe[0] = 0x11;
  ASSERT_TRUE(test::eventually(
      [&] {
        EXPECT_TRUE(client.send(7, universe, 100));
        return !watcher->updates().empty();
      },
      3s));
  EXPECT_EQ(watcher->updates().back().slots[0], 0x11);
}

TEST(OlaDmxClient, AnOladThatStopsReadingFailsASendInsteadOfBlockingIt) {
  if (!test::OladProcess::installed()) GTEST_SKIP() << "olad is not installed (Debian package ola)";
  test::OladProcess olad(test::free_port());
  OlaDmxClient client(olad.rpc_port());
  ASSERT_TRUE(client.connect());
  std::array<std::uint8_t, kDmxUniverseSlots> universe{};
  ASSERT_TRUE(client.send(7, universe, 100));

  // olad hangs: what is sent piles up in the kernel's socket buffers until they are full. libola's
  // socket does not block there: the send that finds no room fails and the client disconnects.
  olad.pause();
  const auto start = std::chrono::steady_clock::now();
  int sends = 0;
  bool failed = false;
  while (!failed && sends < 1'000'000 && std::chrono::steady_clock::now() - start < 20s) {
    failed = !client.send(7, universe, 100);
    ++sends;
  }
  olad.resume();
  EXPECT_TRUE(failed) << sends << " sends went through to a stopped olad";
  EXPECT_FALSE(client.connected());
  RecordProperty("sends_before_failure", sends);
  std::printf("a stopped olad: send %d failed\n", sends);
}

}  // namespace
}  // namespace lipdrive
