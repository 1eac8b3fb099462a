// The serial outputs: wire encoders against known values, and SerialOutput against real
// peers through socat pty pairs (the output writes one end, the test reads the other and
// decodes from the documented format, docs/serial-protocol.md and docs/maestro.md).
#include "captured_log.hpp"
#include "drivers/clock.hpp"
#include "drivers/serial_port.hpp"
#include "drivers/serial_protocol.hpp"
#include "firmware_app/outputs/serial_output.hpp"
#include "serial_peers.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace lipdrive {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
namespace wire = serial_protocol;
using Clock = std::chrono::steady_clock;
using test::Bytes;
using test::decode_frames;
using test::DecodedFrame;
using test::eventually;
using test::FrameStream;
using test::PtyPair;
using test::TempDir;
using Reader = test::PtyReader;

// publish() must never wait for the line. A blocking write would hang until the reader
// reads, so any bound catches it; this one leaves room for preemption on a loaded machine.
constexpr auto kPublishBound = 50ms;

std::string hex(std::span<const std::uint8_t> bytes) {
  std::string text;
  char byte[4];
  for (std::uint8_t value : bytes) {
    std::snprintf(byte, sizeof byte, "%02X ", value);
    text += byte;
  }
  if (!text.empty()) text.pop_back();
  return text;
}

std::vector<std::string> complete_lines(const Bytes& bytes) {
  std::vector<std::string> lines;
  std::string line;
  for (std::uint8_t byte : bytes) {
    if (byte != '\n') {
      line += static_cast<char>(byte);
    } else {
      lines.push_back(line);
      line.clear();
    }
  }
  return lines;
}

struct MaestroCommand {
  std::uint8_t command, servo;
  int target;
};

std::vector<MaestroCommand> decode_maestro(const Bytes& bytes) {
  std::vector<MaestroCommand> commands;
  for (std::size_t at = 0; at + 4 <= bytes.size(); at += 4)
    commands.push_back({bytes[at], bytes[at + 1], bytes[at + 2] | bytes[at + 3] << 7});
  return commands;
}

// ---- fixtures ---------------------------------------------------------------------------

std::vector<ChannelSpec> channels() {
  std::vector<ChannelSpec> specs(4);
  specs[0].name = "open";
  specs[1].name = "width";
  specs[2].name = "protrusion";
  specs[2].out_min = -500;
  specs[2].out_max = 500;
  specs[3].name = "jaw";
  specs[3].out_min = 1000;
  specs[3].out_max = 2000;
  specs[3].neutral = 1500;
  return specs;
}

SerialOutputOptions options_for(const fs::path& device, SerialOutputOptions::Mode mode) {
  SerialOutputOptions options;
  options.mode = mode;
  options.line.device = device;
  options.max_backoff_ms = 200;
  return options;
}

DriveFrame frame_with(std::uint32_t counter, std::vector<double> values) {
  DriveFrame frame;
  frame.counter = counter;
  frame.sequence = counter;
  frame.capture_time_ns = monotonic_ns();
  frame.time_ns = frame.capture_time_ns;
  frame.new_result = true;
  frame.status = kStatusTracking | kStatusOutputsEnabled;
  frame.channel_count = static_cast<int>(values.size());
  std::copy(values.begin(), values.end(), frame.values.begin());
  return frame;
}

// Values that exercise rounding, sign and range: a frame per counter.
DriveFrame test_frame(std::uint32_t counter) {
  const double t = counter * 0.37;
  return frame_with(
      counter, {500 + 499.6 * std::sin(t), 0.5 + counter, -250.5 + std::fmod(t, 1.0) * 100, 1500 + 400 * std::cos(t)});
}

// Publishes and returns how long it took.
std::chrono::nanoseconds timed_publish(SerialOutput& output, const DriveFrame& frame) {
  const auto start = Clock::now();
  output.publish(frame);
  return Clock::now() - start;
}

// ---- encoders -----------------------------------------------------------------------

TEST(SerialProtocol, Crc16ModbusCheckValue) {
  const std::string check = "123456789";
  EXPECT_EQ(wire::crc16_modbus({reinterpret_cast<const std::uint8_t*>(check.data()), check.size()}), 0x4B37);
}

TEST(SerialProtocol, FramedWorkedExampleOfTheDocs) {
  // docs/serial-protocol.md, "Worked example": keep both in step.
  Bytes out(wire::framed_size(3));
  const std::size_t size = wire::encode_framed({0x1234, 12'345'678, kStatusTracking | kStatusOutputsEnabled},
                                               std::vector<double>{530, 210.4, -125}, out);
  ASSERT_EQ(size, 18u);
  EXPECT_EQ(hex(out), "A5 0E 34 12 4E 61 BC 00 21 00 12 02 D2 00 83 FF F3 AA");
}

TEST(SerialProtocol, FrameValuesRoundAndSaturate) {
  EXPECT_EQ(wire::frame_value(2.5), 3);
  EXPECT_EQ(wire::frame_value(-2.5), -3);
  EXPECT_EQ(wire::frame_value(1e9), 32767);
  EXPECT_EQ(wire::frame_value(-1e9), -32768);
  Bytes small(wire::framed_size(2) - 1);
  EXPECT_THROW(wire::encode_framed({}, std::vector<double>{1, 2}, small), std::invalid_argument);
}

TEST(SerialProtocol, LineValuesHaveAtMostThreeDecimalsAndNoTrailingNoise) {
  const auto text = [](double value) {
    char out[wire::kMaxLineValueChars];
    return std::string(out, wire::format_line_value(value, out));
  };
  EXPECT_EQ(text(500), "500");
  EXPECT_EQ(text(0.5), "0.5");
  EXPECT_EQ(text(0.53), "0.53");
  EXPECT_EQ(text(0.1 + 0.2), "0.3");
  EXPECT_EQ(text(-12.125), "-12.125");
  EXPECT_EQ(text(1234.5678), "1234.568");
  EXPECT_EQ(text(-0.0004), "0");
  EXPECT_EQ(text(0), "0");
  EXPECT_EQ(text(1e12), "999999999.999");
  EXPECT_EQ(text(-1e12), "-999999999.999");

  const std::vector<std::string> names{"open", "width"};
  Bytes out(wire::line_size_bound(names));
  const std::size_t size = wire::encode_line(names, std::vector<double>{0.53, 0.21}, out);
  EXPECT_EQ(std::string(out.begin(), out.begin() + static_cast<std::ptrdiff_t>(size)), "open=0.53 width=0.21\n");
}

TEST(SerialProtocol, MaestroSetTargetInQuarterMicroseconds) {
  // Pololu's own example: 1500 µs on servo 0 is 0x84 0x00 0x70 0x2E.
  Bytes out(8);
  ASSERT_EQ(wire::encode_maestro(std::vector<int>{0, 5}, std::vector<double>{1500, 992.3}, out), 8u);
  EXPECT_EQ(hex(out), "84 00 70 2E 84 05 01 1F");  // 992.3 µs -> 3969 quarter-µs
  EXPECT_EQ(wire::maestro_target(5000), wire::kMaestroMaxTarget);
  EXPECT_EQ(wire::maestro_target(-3), 0);
}

// ---- construction -----------------------------------------------------------------------

TEST(SerialOutput, RejectsBadConfigurationNamingIt) {
  const auto specs = channels();
  auto options = options_for("/nonexistent/tty", SerialOutputOptions::Mode::kFramed);
  options.channels = {"open", "jwa"};
  try {
    SerialOutput output(options, specs);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("'jwa'"), std::string::npos) << error.what();
  }
  options.channels.clear();
  options.line.baud = 12345;
  try {
    SerialOutput output(options, specs);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_NE(std::string(error.what()).find("12345"), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("921600"), std::string::npos) << error.what();
  }

  auto maestro = options_for("/nonexistent/tty", SerialOutputOptions::Mode::kMaestro);
  maestro.servos = {{"open", 0}};  // 0..1000 is not a pulse width (0 would switch the servo off)
  EXPECT_THROW(SerialOutput(maestro, specs), std::invalid_argument);
  maestro.servos = {{"jaw", 0}, {"jaw", 0}};
  EXPECT_THROW(SerialOutput(maestro, specs), std::invalid_argument);
  maestro.servos = {{"jaw", 24}};
  EXPECT_THROW(SerialOutput(maestro, specs), std::invalid_argument);
}

TEST(SerialOutput, MissingDeviceStartsUnhealthyAndPublishesFast) {
  const auto specs = channels();
  SerialOutput output(options_for("/nonexistent/tty", SerialOutputOptions::Mode::kFramed), specs);
  EXPECT_FALSE(output.healthy());
  EXPECT_EQ(output.describe(), "serial framed /nonexistent/tty 115200 8N1");
  // 300 ms span several failing reopen attempts (100, 200, 200 ms apart).
  std::uint32_t published = 0;
  const auto until = Clock::now() + 300ms;
  eventually([&] {
    EXPECT_LT(timed_publish(output, test_frame(published++)), kPublishBound);
    return Clock::now() > until;
  });
  EXPECT_FALSE(output.healthy());
  EXPECT_EQ(output.counters().offline, published);
  EXPECT_EQ(output.counters().written, 0u);
}

// The neutral pose at the daemon's stop, on a line that is gone: said, not left to be guessed.
TEST(SerialOutput, ANeutralPoseThatCannotBeSentIsSaid) {
  const auto specs = channels();
  SerialOutput output(options_for("/nonexistent/tty", SerialOutputOptions::Mode::kFramed), specs);
  const testing::CapturedLog log;
  output.publish_last(test_frame(1));
  const auto warnings = log.messages(spdlog::level::warn);
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_EQ(warnings[0], "serial framed /nonexistent/tty 115200 8N1: the neutral pose was not sent (the line is gone)");
}

TEST(SerialPort, RefusedRs485IsReportedNotFatal) {
  TempDir dir;
  PtyPair pty(dir.path());
  SerialPortSettings settings;
  settings.device = pty.a.string();
  settings.rs485 = true;
  SerialPort port(settings);  // a pty has no RS-485 mode
  EXPECT_FALSE(port.rs485_active());
  EXPECT_FALSE(port.rs485_refusal().empty());
  const std::uint8_t byte = 0x55;
  EXPECT_EQ(port.write_some({&byte, 1}).status, SerialPort::WriteStatus::kWritten);
  settings.device = (dir.path() / "missing").string();
  EXPECT_THROW(SerialPort{settings}, SerialPortError);
}

// ---- against a real peer ------------------------------------------------------------

TEST(SerialOutput, FramedFramesArriveWithValidCrcAndTheValuesPublished) {
  TempDir dir;
  PtyPair pty(dir.path());
  Reader reader(pty.b);
  const auto specs = channels();
  auto options = options_for(pty.a, SerialOutputOptions::Mode::kFramed);
  options.channels = {"protrusion", "open", "jaw"};  // a subset, in another order
  SerialOutput output(options, specs);
  ASSERT_TRUE(output.healthy());

  constexpr std::uint32_t kFrames = 60;
  for (std::uint32_t i = 0; i < kFrames; ++i) {
    output.publish(test_frame(1000 + i));
    std::this_thread::sleep_for(1ms);
  }
  FrameStream stream;
  ASSERT_TRUE(eventually([&] { return (stream = decode_frames(reader.read_available())).frames.size() >= kFrames; }));
  EXPECT_EQ(stream.skipped_bytes, 0u);
  ASSERT_EQ(stream.frames.size(), kFrames);
  for (std::uint32_t i = 0; i < kFrames; ++i) {
    const DriveFrame sent = test_frame(1000 + i);
    const DecodedFrame& got = stream.frames[i];
    EXPECT_EQ(got.sequence, 1000 + i);
    EXPECT_EQ(got.status, sent.status);
    ASSERT_EQ(got.values.size(), 3u);
    EXPECT_EQ(got.values[0], std::lround(sent.values[2])) << "frame " << i;
    EXPECT_EQ(got.values[1], std::lround(sent.values[0])) << "frame " << i;
    EXPECT_EQ(got.values[2], std::lround(sent.values[3])) << "frame " << i;
  }
  EXPECT_GE(stream.frames.back().time_us - stream.frames.front().time_us, (kFrames - 1) * 1000u);
  EXPECT_EQ(output.counters().written, kFrames);
  EXPECT_EQ(output.wire_latency()->count(), kFrames);
  std::printf("framed over pty: capture->wire p50 %.2f ms, p99 %.2f ms\n", output.wire_latency()->quantile_ms(0.5),
              output.wire_latency()->quantile_ms(0.99));
}

TEST(SerialOutput, LineModeSendsNameValuePairs) {
  TempDir dir;
  PtyPair pty(dir.path());
  Reader reader(pty.b);
  const auto specs = channels();
  SerialOutput output(options_for(pty.a, SerialOutputOptions::Mode::kLine), specs);
  output.publish(frame_with(1, {530, 210.25, -0.0004, 1500}));
  output.publish(frame_with(2, {0.1 + 0.2, 1000, -499.5, 1234.5678}));
  std::vector<std::string> lines;
  ASSERT_TRUE(eventually([&] { return (lines = complete_lines(reader.read_available())).size() >= 2; }));
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0], "open=530 width=210.25 protrusion=0 jaw=1500");
  EXPECT_EQ(lines[1], "open=0.3 width=1000 protrusion=-499.5 jaw=1234.568");
}

TEST(SerialOutput, MaestroModeSendsSetTargetPerServo) {
  TempDir dir;
  PtyPair pty(dir.path());
  Reader reader(pty.b);
  auto specs = channels();
  specs[1].out_min = 500;  // "width" drives a second servo, 500..2500 µs
  specs[1].out_max = 2500;
  auto options = options_for(pty.a, SerialOutputOptions::Mode::kMaestro);
  options.servos = {{"jaw", 0}, {"width", 7}};
  SerialOutput output(options, specs);
  output.publish(frame_with(1, {0, 2500, 0, 1500}));
  output.publish(frame_with(2, {0, 612.3, 0, 1000.25}));
  std::vector<MaestroCommand> commands;
  ASSERT_TRUE(eventually([&] { return (commands = decode_maestro(reader.read_available())).size() >= 4; }));
  ASSERT_EQ(commands.size(), 4u);
  const int expected[4][2] = {{0, 6000}, {7, 10000}, {0, 4001}, {7, 2449}};
  for (int i = 0; i < 4; ++i) {
    EXPECT_EQ(commands[static_cast<std::size_t>(i)].command, 0x84);
    EXPECT_EQ(commands[static_cast<std::size_t>(i)].servo, expected[i][0]);
    EXPECT_EQ(commands[static_cast<std::size_t>(i)].target, expected[i][1]);
  }
}

TEST(SerialOutput, RecoversWhenThePortVanishesAndReturns) {
  TempDir dir;
  auto pty = std::make_unique<PtyPair>(dir.path());
  auto reader = std::make_unique<Reader>(pty->b);
  const auto specs = channels();
  SerialOutput output(options_for(pty->a, SerialOutputOptions::Mode::kFramed), specs);
  std::uint32_t counter = 0;
  std::chrono::nanoseconds slowest{0};
  const auto publish = [&] {
    slowest = std::max(slowest, timed_publish(output, test_frame(++counter)));
    return true;
  };

  publish();
  ASSERT_TRUE(eventually([&] { return !decode_frames(reader->read_available()).frames.empty(); }));

  reader.reset();
  pty->stop();
  ASSERT_TRUE(eventually([&] { return publish() && !output.healthy(); }));
  const auto lost_at = output.counters();
  for (int i = 0; i < 20; ++i) publish();  // keeps failing fast, reopen attempts included
  EXPECT_FALSE(output.healthy());
  EXPECT_GE(output.counters().offline, lost_at.offline + 20);

  pty = std::make_unique<PtyPair>(dir.path());  // the same link paths
  reader = std::make_unique<Reader>(pty->b);
  ASSERT_TRUE(eventually([&] { return publish() && output.healthy(); }));
  FrameStream stream;
  ASSERT_TRUE(eventually([&] {
    publish();
    return (stream = decode_frames(reader->read_available())).frames.size() >= 5;
  }));
  EXPECT_EQ(stream.skipped_bytes, 0u);
  for (std::size_t i = 1; i < stream.frames.size(); ++i)
    EXPECT_EQ(stream.frames[i].sequence, static_cast<std::uint16_t>(stream.frames[i - 1].sequence + 1));
  EXPECT_EQ(output.counters().reopens, 1u);
  EXPECT_LT(slowest, kPublishBound);
  std::printf("vanish/return: slowest publish %.3f ms\n", slowest.count() / 1e6);
}

TEST(SerialOutput, AReaderThatNeverReadsNeverBlocksPublish) {
  TempDir dir;
  PtyPair pty(dir.path());
  Reader reader(pty.b);
  const auto specs = channels();
  SerialOutput output(options_for(pty.a, SerialOutputOptions::Mode::kFramed), specs);

  // ~36 KB fill the pty pair and socat; 4000 frames of 20 bytes are twice that.
  std::vector<std::int64_t> durations_ns;
  std::uint32_t counter = 0;
  for (; counter < 4000; ++counter) durations_ns.push_back(timed_publish(output, test_frame(counter)).count());
  std::sort(durations_ns.begin(), durations_ns.end());
  const auto counters = output.counters();
  EXPECT_GT(counters.dropped, 0u);
  EXPECT_GT(counters.written, 0u);
  // Every publish is written or dropped, except perhaps the last, whose tail may still wait.
  EXPECT_GE(counters.written + counters.dropped, 3999u);
  EXPECT_LE(counters.written + counters.dropped, 4000u);
  EXPECT_TRUE(output.healthy());
  EXPECT_LT(std::chrono::nanoseconds(durations_ns.back()), kPublishBound);
  std::printf("full pty: %llu written, %llu dropped, publish p50 %.1f us, p99 %.1f us, max %.1f us\n",
              static_cast<unsigned long long>(counters.written), static_cast<unsigned long long>(counters.dropped),
              durations_ns[durations_ns.size() / 2] / 1e3, durations_ns[durations_ns.size() * 99 / 100] / 1e3,
              durations_ns.back() / 1e3);

  // Draining: every byte that arrived belongs to a whole frame, and the newest values flow again.
  FrameStream stream;
  ASSERT_TRUE(eventually([&] {
    output.publish(test_frame(counter++));
    stream = decode_frames(reader.read_available());
    return !stream.frames.empty() && stream.frames.back().sequence >= 4020;
  }));
  EXPECT_EQ(stream.skipped_bytes, 0u);
  for (std::size_t i = 1; i < stream.frames.size(); ++i)
    EXPECT_LT(stream.frames[i - 1].sequence, stream.frames[i].sequence);
}

}  // namespace
}  // namespace lipdrive
