// The Modbus outputs against real peers: libmodbus masters reading and writing the register
// map over loopback TCP and over an RTU pty pair (socat), the client output writing to a
// libmodbus slave that goes away and comes back, the server under garbage and load, and a
// server whose port is taken or whose device is missing at start.
#include "captured_log.hpp"
#include "daemon_process.hpp"
#include "drivers/clock.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/pipeline.hpp"
#include "firmware_app/outputs/modbus_client_output.hpp"
#include "firmware_app/outputs/modbus_server_output.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"
#include "shared_predictor.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <modbus/modbus-rtu.h>
#include <modbus/modbus-tcp.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using ::testing::HasSubstr;
namespace map = modbus_map;

using test::kClip;
using test::kModel;

const std::vector<ChannelSpec> kChannels = {
    {.name = "open", .signal = Signal::kOpen, .out_min = 0, .out_max = 1000, .neutral = 100},
    {.name = "width", .signal = Signal::kWidth, .out_min = 1000, .out_max = 2000, .neutral = 1500},
};
const int kChannelCount = static_cast<int>(kChannels.size());

bool wait_for(const std::function<bool()>& condition, std::chrono::milliseconds limit = 10s) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}

ModbusServerOptions tcp_server_options() {
  ModbusServerOptions options;
  options.link.address = "127.0.0.1";
  options.link.port = 0;  // any free port; the test reads it back
  return options;
}

/// A libmodbus master on the loopback port.
ModbusContext tcp_master(int port) {
  ModbusContext master(modbus_new_tcp("127.0.0.1", port));
  EXPECT_EQ(modbus_connect(master.get()), 0) << modbus_strerror(errno);
  modbus_set_response_timeout(master.get(), 2, 0);
  return master;
}

std::vector<std::uint16_t> read_input(modbus_t* master, int address, int count) {
  std::vector<std::uint16_t> registers(static_cast<std::size_t>(count));
  EXPECT_EQ(modbus_read_input_registers(master, address, count, registers.data()), count) << modbus_strerror(errno);
  return registers;
}

std::uint16_t read_holding(modbus_t* master, int address) {
  std::uint16_t value = 0;
  EXPECT_EQ(modbus_read_registers(master, address, 1, &value), 1) << modbus_strerror(errno);
  return value;
}

void write_holding(modbus_t* master, int address, std::uint16_t value) {
  EXPECT_EQ(modbus_write_register(master, address, value), 1) << modbus_strerror(errno);
}

/// errno of a request that must fail with a Modbus exception.
int exception_of(int result) { return result == -1 ? errno : 0; }

DriveFrame frame_with(std::uint32_t counter, double open, double width) {
  DriveFrame frame;
  frame.counter = counter;
  frame.sequence = 0x1'0002'0003;  // low 32 bits: 0x0002'0003
  frame.capture_time_ns = monotonic_ns();
  frame.new_result = true;
  frame.status = kStatusTracking | kStatusOutputsEnabled;
  frame.fps = 29.97f;
  frame.latency_ms = 70.123f;  // 70123 µs: more than 16 bits
  frame.channel_count = kChannelCount;
  frame.values[0] = open;
  frame.values[1] = width;
  return frame;
}

/// The register map without a pipeline: everything the server shows for one known frame,
/// and every control register, over one master.
void check_register_map(modbus_t* master, ModbusServerOutput& output, DriveControl& control) {
  // Before the first frame: the neutral pose.
  auto input = read_input(master, 0, map::kFirstChannel + kChannelCount);
  EXPECT_EQ(input[map::kChannelCount], kChannelCount);
  EXPECT_EQ(input[map::kFirstChannel], 100);
  EXPECT_EQ(input[map::kFirstChannel + 1], 1500);

  output.publish(frame_with(0x1'2345, 412.6, 70000));
  input = read_input(master, 0, map::kFirstChannel + kChannelCount);
  EXPECT_EQ(input[map::kStatus], kStatusTracking | kStatusOutputsEnabled);
  EXPECT_EQ(input[map::kHeartbeat], 0x2345);
  EXPECT_EQ(input[map::kSequenceHigh], 0x0002);
  EXPECT_EQ(input[map::kSequenceLow], 0x0003);
  EXPECT_EQ((input[map::kLatencyUsHigh] << 16) | input[map::kLatencyUsLow], 70123);
  EXPECT_EQ(input[map::kFpsTenths], 300);
  EXPECT_EQ(input[map::kFirstChannel], 413) << "rounded";
  EXPECT_EQ(input[map::kFirstChannel + 1], 65535) << "clamped";

  EXPECT_EQ(read_holding(master, map::kOutputEnable), 1);
  write_holding(master, map::kOutputEnable, 0);
  EXPECT_FALSE(control.outputs_enabled);
  EXPECT_EQ(read_holding(master, map::kOutputEnable), 0);
  write_holding(master, map::kOutputEnable, 1);
  EXPECT_TRUE(control.outputs_enabled);

  const std::uint32_t calibrations = control.calibrate_requests;
  write_holding(master, map::kCalibrate, 1);
  write_holding(master, map::kCalibrate, 1);
  EXPECT_EQ(control.calibrate_requests, calibrations + 2) << "one request per write of 1";
  EXPECT_EQ(read_holding(master, map::kCalibrate), 0);

  write_holding(master, map::kRecord, 1);
  EXPECT_EQ(control.recording_request, 1);
  EXPECT_EQ(read_holding(master, map::kRecord), 0) << "not recording until the status word says so";
  DriveFrame recording = frame_with(0x1'2346, 412.6, 70000);
  recording.status |= kStatusRecording;
  output.publish(recording);
  EXPECT_EQ(read_holding(master, map::kRecord), 1);
  write_holding(master, map::kRecord, 0);
  EXPECT_EQ(control.recording_request, 0);
  output.publish(frame_with(0x1'2347, 412.6, 70000));
  EXPECT_EQ(read_holding(master, map::kRecord), 0);

  EXPECT_EQ(read_holding(master, map::kFirstOverride + 1), map::kNoOverride);
  const std::uint16_t both[] = {250, 1800};
  EXPECT_EQ(modbus_write_registers(master, map::kFirstOverride, 2, both), 2);
  EXPECT_EQ(control.overrides[0], 250);
  EXPECT_EQ(control.overrides[1], 1800);
  EXPECT_EQ(read_holding(master, map::kFirstOverride + 1), 1800);
  write_holding(master, map::kFirstOverride + 1, map::kNoOverride);
  EXPECT_TRUE(std::isnan(control.overrides[1].load()));
  control.overrides[0] = ChannelBank::kNoOverride;

  // Beyond the map: exceptions, and nothing is written.
  std::uint16_t value = 0;
  EXPECT_EQ(exception_of(modbus_read_input_registers(master, map::kFirstChannel + kChannelCount, 1, &value)),
            EMBXILADD);
  EXPECT_EQ(exception_of(modbus_write_registers(master, map::kFirstOverride + 1, 2, both)), EMBXILADD);
  EXPECT_TRUE(std::isnan(control.overrides[1].load())) << "a rejected write changes nothing";
  std::uint8_t bits[1];
  EXPECT_EQ(exception_of(modbus_read_bits(master, 0, 1, bits)), EMBXILADD) << "the map has no coils";
}

// ---------------------------------------------------------------- register map, no pipeline

TEST(ModbusServer, TcpRegisterMapAndControlRegisters) {
  DriveControl control;
  ModbusServerOutput output(tcp_server_options(), kChannels, control);
  ASSERT_GT(output.port(), 0);
  EXPECT_THAT(output.describe(), HasSubstr(fmt::format("tcp 127.0.0.1:{}", output.port())));
  const ModbusContext master = tcp_master(output.port());
  check_register_map(master.get(), output, control);
}

TEST(ModbusServer, RtuServesTheSameMapOverASerialLine) {
  const test::TempDir dir;
  auto pty = std::make_unique<test::PtyPair>(dir.path());
  const test::PtyPair& line = *pty;
  ModbusServerOptions options;
  options.link.transport = ModbusEndpoint::Transport::kRtu;
  options.link.line.device = line.a;
  options.link.line.baud = 115200;
  options.link.line.rs485 = true;  // a pty cannot do RS-485: logged, not fatal
  options.link.unit_id = 7;
  DriveControl control;
  ModbusServerOutput output(options, kChannels, control);
  EXPECT_THAT(output.describe(), HasSubstr("rtu"));

  const ModbusContext master(modbus_new_rtu(line.b.c_str(), 115200, 'N', 8, 1));
  ASSERT_EQ(modbus_connect(master.get()), 0) << modbus_strerror(errno);
  modbus_set_response_timeout(master.get(), 1, 0);
  modbus_set_slave(master.get(), 7);
  check_register_map(master.get(), output, control);

  // Another unit's requests are not answered, and that unit's answer (sent here by hand, as
  // unit 8 would on a shared bus) is not taken for a request.
  modbus_set_slave(master.get(), 8);
  modbus_set_response_timeout(master.get(), 0, 200'000);
  std::uint16_t value = 0;
  EXPECT_EQ(modbus_read_input_registers(master.get(), 0, 1, &value), -1);
  EXPECT_EQ(errno, ETIMEDOUT);
  const std::uint8_t unit8_answer[] = {8, MODBUS_FC_READ_INPUT_REGISTERS, 2, 0x12, 0x34};
  ASSERT_GT(modbus_send_raw_request(master.get(), unit8_answer, sizeof unit8_answer), 0);
  modbus_set_slave(master.get(), 7);
  EXPECT_EQ(read_input(master.get(), map::kChannelCount, 1)[0], kChannelCount) << "unit 7 still answers";

  EXPECT_TRUE(output.healthy());
  pty.reset();  // the "adapter" is unplugged
  EXPECT_TRUE(wait_for([&] { return !output.healthy(); }, 2s));
}

std::size_t open_descriptors() {
  return static_cast<std::size_t>(std::distance(std::filesystem::directory_iterator("/proc/self/fd"), {}));
}

TEST(ModbusServer, AnRtuServerClosesItsLineWhenItGoes) {
  const test::TempDir dir;
  const test::PtyPair line(dir.path());
  ModbusServerOptions options;
  options.link.transport = ModbusEndpoint::Transport::kRtu;
  options.link.line.device = line.a;
  options.link.line.baud = 115200;
  DriveControl control;
  const std::size_t before = open_descriptors();
  for (int reload = 0; reload < 3; ++reload) ModbusServerOutput(options, kChannels, control);
  EXPECT_EQ(open_descriptors(), before) << "each reload of the daemon builds its outputs again";
}

// ---------------------------------------------------------------- a port or device not there at start

TEST(ModbusServer, ATcpServerWhosePortIsTakenAtStartServesOnceItIsFree) {
  const testing::CapturedLog log;
  test::PortInUse taken;  // another program listens there
  ModbusServerOptions options = tcp_server_options();
  options.link.port = taken.port();
  DriveControl control;
  ModbusServerOutput output(options, kChannels, control);
  EXPECT_FALSE(output.healthy()) << "reported failing, not thrown";
  EXPECT_THAT(output.describe(), HasSubstr(fmt::format("tcp 127.0.0.1:{}", taken.port())));
  std::this_thread::sleep_for(500ms);  // a few tries while the port is still taken
  EXPECT_FALSE(output.healthy());
  const std::vector<std::string> errors = log.messages(spdlog::level::err);
  ASSERT_EQ(errors.size(), 1u) << "logged once, not once per try";
  EXPECT_THAT(errors[0], HasSubstr(fmt::format("modbus server tcp 127.0.0.1:{}: cannot listen: Address already in use; "
                                               "trying again with back-off",
                                               taken.port())));

  taken.release();
  ASSERT_TRUE(wait_for([&] { return output.healthy(); }, 20s)) << "listens once the port is free";
  EXPECT_EQ(output.port(), options.link.port);
  EXPECT_THAT(log.messages(spdlog::level::info), ::testing::Contains(HasSubstr("listening now")));
  const ModbusContext master = tcp_master(output.port());
  check_register_map(master.get(), output, control);
}

TEST(ModbusServer, AnRtuServerWhoseDeviceIsMissingAtStartOpensItWhenItAppears) {
  const testing::CapturedLog log;
  const test::TempDir dir;
  ModbusServerOptions options;
  options.link.transport = ModbusEndpoint::Transport::kRtu;
  options.link.line.device = dir.path() / "line" / "a";  // the PtyPair below makes it
  options.link.line.baud = 115200;
  options.link.unit_id = 7;
  DriveControl control;
  ModbusServerOutput output(options, kChannels, control);
  EXPECT_FALSE(output.healthy()) << "reported failing, not thrown";
  const std::vector<std::string> errors = log.messages(spdlog::level::err);
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_THAT(errors[0], HasSubstr("cannot open: No such file or directory; trying again with back-off"));
  std::this_thread::sleep_for(300ms);  // a few tries while the device is missing
  EXPECT_FALSE(output.healthy());

  const test::PtyPair line(dir.path() / "line");  // the adapter is plugged in
  ASSERT_TRUE(wait_for([&] { return output.healthy(); }, 20s)) << "opens the device once it is there";
  EXPECT_THAT(log.messages(spdlog::level::info), ::testing::Contains(HasSubstr("serial line open")));
  const ModbusContext master(modbus_new_rtu(line.b.c_str(), 115200, 'N', 8, 1));
  ASSERT_EQ(modbus_connect(master.get()), 0) << modbus_strerror(errno);
  modbus_set_response_timeout(master.get(), 1, 0);
  modbus_set_slave(master.get(), 7);
  check_register_map(master.get(), output, control);
  EXPECT_EQ(log.count(spdlog::level::err), 1) << "nothing failed after the device appeared";
}

TEST(ModbusServer, StopsPromptlyWhileWaitingForItsPort) {
  test::PortInUse taken;
  ModbusServerOptions options = tcp_server_options();
  options.link.port = taken.port();
  DriveControl control;
  auto output = std::make_unique<ModbusServerOutput>(options, kChannels, control);
  std::this_thread::sleep_for(1600ms);  // tries at 0.1, 0.3, 0.7 and 1.5 s; the next one waits 1.6 s
  EXPECT_FALSE(output->healthy());
  const auto start = std::chrono::steady_clock::now();
  output.reset();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 1s) << "the back-off's wait is cut short, not sat out";
}

// ---------------------------------------------------------------- robustness

/// A raw TCP connection, for what a libmodbus master would never send.
class RawConnection {
 public:
  explicit RawConnection(int port) : fd_(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  }
  ~RawConnection() { ::close(fd_); }
  void send(const std::vector<std::uint8_t>& bytes) const {
    EXPECT_EQ(::send(fd_, bytes.data(), bytes.size(), MSG_NOSIGNAL), static_cast<ssize_t>(bytes.size()));
  }
  /// What arrives within `limit`; stops at the peer's close.
  std::vector<std::uint8_t> receive(std::size_t expected, std::chrono::milliseconds limit) const {
    std::vector<std::uint8_t> bytes;
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (bytes.size() < expected && std::chrono::steady_clock::now() < deadline) {
      pollfd readable{fd_, POLLIN, 0};
      if (::poll(&readable, 1, 10) != 1) continue;
      std::uint8_t chunk[300];
      const ssize_t size = ::recv(fd_, chunk, sizeof chunk, 0);
      if (size <= 0) break;
      bytes.insert(bytes.end(), chunk, chunk + size);
    }
    return bytes;
  }
  /// One byte; false once the server has closed the connection.
  bool try_send(std::uint8_t byte) const { return ::send(fd_, &byte, 1, MSG_NOSIGNAL) == 1; }
  /// True when the server closes the connection within `limit` (what it sent first is skipped).
  bool closed_within(std::chrono::milliseconds limit) const {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      pollfd readable{fd_, POLLIN, 0};
      if (::poll(&readable, 1, 10) != 1) continue;
      std::uint8_t chunk[300];
      if (::recv(fd_, chunk, sizeof chunk, 0) <= 0) return true;
    }
    return false;
  }

 private:
  int fd_;
};

/// A TCP server publishing channel 1 at 300, and a client of it (the bystander) that has
/// read it once; the tests send bad requests beside it.
class ModbusServerWithBystander : public ::testing::Test {
 protected:
  void SetUp() override {
    output.publish(frame_with(1, 300, 1200));
    EXPECT_EQ(read_input(bystander.get(), map::kFirstChannel, 1)[0], 300);
  }

  DriveControl control;
  ModbusServerOutput output{tcp_server_options(), kChannels, control};
  const ModbusContext bystander = tcp_master(output.port());
};

TEST_F(ModbusServerWithBystander, ReservedRegistersReadZeroWhateverIsWritten) {
  for (int reg = map::kRecord + 1; reg < map::kFirstOverride; ++reg) {
    ASSERT_EQ(modbus_write_register(bystander.get(), reg, 0x1234), 1) << modbus_strerror(errno);
    std::uint16_t value = 0xFFFF;
    ASSERT_EQ(modbus_read_registers(bystander.get(), reg, 1, &value), 1) << modbus_strerror(errno);
    EXPECT_EQ(value, 0) << "holding register " << reg;
  }
}

TEST_F(ModbusServerWithBystander, GarbageAndBadRequestsGetExceptionsAndOthersAreStillServed) {
  // Function 0x55 does not exist: exception 1 (illegal function), same transaction id.
  RawConnection raw(output.port());
  raw.send({0x12, 0x34, 0x00, 0x00, 0x00, 0x02, 0x01, 0x55});
  EXPECT_THAT(raw.receive(9, 2s), ::testing::ElementsAre(0x12, 0x34, 0x00, 0x00, 0x00, 0x03, 0x01, 0xD5, 0x01));
  // Read 0 registers: exception 3 (illegal data value).
  raw.send({0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04, 0x00, 0x00, 0x00, 0x00});
  EXPECT_THAT(raw.receive(9, 2s), ::testing::ElementsAre(0x00, 0x02, 0x00, 0x00, 0x00, 0x03, 0x01, 0x84, 0x03));
  // Write beyond the map: exception 2 (illegal data address).
  raw.send({0x00, 0x03, 0x00, 0x00, 0x00, 0x06, 0x01, 0x06, 0x01, 0x00, 0x00, 0x01});
  EXPECT_THAT(raw.receive(9, 2s), ::testing::ElementsAre(0x00, 0x03, 0x00, 0x00, 0x00, 0x03, 0x01, 0x86, 0x02));

  // Garbage, and a request cut short that never completes: those connections are dropped
  // (or answered), the others are served meanwhile.
  RawConnection garbage(output.port()), stalled(output.port());
  std::vector<std::uint8_t> noise(200);
  for (std::size_t i = 0; i < noise.size(); ++i) noise[i] = static_cast<std::uint8_t>(i * 37 + 11);
  garbage.send(noise);
  stalled.send({0x00, 0x04, 0x00, 0x00, 0x00, 0x06, 0x01, 0x10, 0x00});
  garbage.receive(1000, 300ms);
  for (int i = 0; i < 20; ++i)
    EXPECT_EQ(read_input(bystander.get(), map::kFirstChannel, 1)[0], 300) << "the bystander is still served";
  const ModbusContext newcomer = tcp_master(output.port());
  EXPECT_EQ(read_input(newcomer.get(), map::kChannelCount, 1)[0], kChannelCount);
  EXPECT_TRUE(stalled.receive(1, 1s).empty()) << "a half request gets no answer";
}

// The map lists functions 1-6, 15, 16, 22 and 23; libmodbus answers report server id (0x11)
// itself, with its version string. The others get exception 1, and the rest of a request
// libmodbus does not parse (0x2B's MEI type and object id) is not taken for the next one.
TEST_F(ModbusServerWithBystander, FunctionsTheMapDoesNotListGetIllegalFunction) {
  RawConnection raw(output.port());
  raw.send({0x00, 0x05, 0x00, 0x00, 0x00, 0x05, 0x01, 0x2B, 0x0E, 0x01, 0x00});  // read device identification
  EXPECT_THAT(raw.receive(9, 2s), ::testing::ElementsAre(0x00, 0x05, 0x00, 0x00, 0x00, 0x03, 0x01, 0xAB, 0x01));
  raw.send({0x00, 0x06, 0x00, 0x00, 0x00, 0x02, 0x01, 0x11});  // report server id
  EXPECT_THAT(raw.receive(9, 2s), ::testing::ElementsAre(0x00, 0x06, 0x00, 0x00, 0x00, 0x03, 0x01, 0x91, 0x01));
  std::uint8_t id[MODBUS_MAX_PDU_LENGTH];
  EXPECT_EQ(exception_of(modbus_report_slave_id(bystander.get(), sizeof id, id)), EMBXILFUN);
  EXPECT_EQ(read_input(bystander.get(), map::kFirstChannel, 1)[0], 300);
}

// libmodbus sleeps its response timeout (500 ms by default) before it answers a request with
// an illegal count, on the one server thread: fuzz_modbus ran at one input a second. The
// server sets that sleep to nothing on TCP, so the other clients are not held up.
TEST_F(ModbusServerWithBystander, AnIllegalCountDoesNotHoldUpTheOtherClients) {
  RawConnection raw(output.port());
  for (int round = 0; round < 3; ++round) {
    // Read 0 input registers: exception 3 (illegal data value).
    raw.send({0x00, 0x02, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04, 0x00, 0x00, 0x00, 0x00});
    std::this_thread::sleep_for(20ms);  // the server is answering it (and was asleep there)
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(read_input(bystander.get(), map::kFirstChannel, 1)[0], 300);
    const auto waited = std::chrono::steady_clock::now() - start;
    EXPECT_LT(waited, 250ms) << "the bystander waited "
                             << std::chrono::duration_cast<std::chrono::milliseconds>(waited).count() << " ms";
    EXPECT_THAT(raw.receive(9, 2s), ::testing::ElementsAre(0x00, 0x02, 0x00, 0x00, 0x00, 0x03, 0x01, 0x84, 0x03));
  }
}

// A PLC that power-cycles leaves its connection half-open: it never sends again. Before, a
// server full of those refused every new connection, the PLC's too, for ever.
TEST(ModbusServer, AFullServerClosesTheQuietestClientForANewOne) {
  ModbusServerOptions options = tcp_server_options();
  options.max_clients = 3;
  DriveControl control;
  ModbusServerOutput output(options, kChannels, control);
  const ModbusContext poller = tcp_master(output.port());
  std::vector<std::unique_ptr<RawConnection>> silent;
  for (int i = 0; i < 2; ++i) {
    silent.push_back(std::make_unique<RawConnection>(output.port()));
    std::this_thread::sleep_for(50ms);  // accepted in this order
  }
  EXPECT_EQ(read_input(poller.get(), map::kChannelCount, 1)[0], kChannelCount);  // the poller is the liveliest
  const auto quiet_for_long_enough = [] {
    std::this_thread::sleep_for(std::chrono::milliseconds(ModbusServer::kQuietBeforeClosingMs + 200));
  };

  // Each life of the PLC leaves its connection open and silent, as a power cut would; the next
  // comes up a little later.
  std::vector<ModbusContext> plc_lives;
  for (int reboot = 0; reboot < 3; ++reboot) {
    quiet_for_long_enough();
    EXPECT_EQ(read_input(poller.get(), map::kChannelCount, 1)[0], kChannelCount) << "the poller was not closed";
    plc_lives.push_back(tcp_master(output.port()));
    EXPECT_EQ(read_input(plc_lives.back().get(), map::kChannelCount, 1)[0], kChannelCount) << "life " << reboot;
  }
  for (std::size_t i = 0; i < silent.size(); ++i)
    EXPECT_TRUE(silent[i]->closed_within(5s)) << "silent connection " << i;

  // Every place taken by a client that asked within the last 2 s: a newcomer is refused, and
  // the poller keeps its place.
  EXPECT_EQ(read_input(plc_lives.back().get(), map::kChannelCount, 1)[0], kChannelCount);
  EXPECT_EQ(read_input(plc_lives[1].get(), map::kChannelCount, 1)[0], kChannelCount);
  EXPECT_EQ(read_input(poller.get(), map::kChannelCount, 1)[0], kChannelCount);
  const ModbusContext newcomer = tcp_master(output.port());
  std::uint16_t word = 0;
  EXPECT_EQ(modbus_read_input_registers(newcomer.get(), map::kChannelCount, 1, &word), -1) << "refused";
  EXPECT_EQ(read_input(poller.get(), map::kChannelCount, 1)[0], kChannelCount) << "the poller kept its place";
}

// libmodbus reads a request until it is complete, waiting up to its byte timeout (50 ms) for
// each byte: a client sending one every 40 ms held the one server thread, every other client
// with it, for the whole request (10 s for a long function 16).
TEST_F(ModbusServerWithBystander, ASlowRequestDoesNotHoldUpTheOtherClientsAndIsDropped) {
  RawConnection dribbler(output.port());
  // Function 16, 123 registers: 259 bytes, 10 s at one byte per 40 ms.
  std::vector<std::uint8_t> request(7 + 6 + 2 * 123, 0x01);
  const std::uint8_t header[] = {0x00, 0x07, 0x00, 0x00, 0x00, 7 + 2 * 123, 0x01, 0x10, 0x00, 100, 0x00, 123, 2 * 123};
  std::ranges::copy(header, request.begin());
  std::atomic<bool> refused{false};
  std::thread slow([&] {
    const auto until = std::chrono::steady_clock::now() + 4s;
    for (std::size_t i = 0; i < request.size() && std::chrono::steady_clock::now() < until; ++i) {
      if (!dribbler.try_send(request[i])) {
        refused = true;
        return;
      }
      std::this_thread::sleep_for(40ms);
    }
  });
  for (int i = 0; i < 40; ++i) {
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(read_input(bystander.get(), map::kFirstChannel, 1)[0], 300);
    const auto waited = std::chrono::steady_clock::now() - start;
    EXPECT_LT(waited, 1s) << "request " << i << " waited "
                          << std::chrono::duration_cast<std::chrono::milliseconds>(waited).count() << " ms";
    std::this_thread::sleep_for(50ms);
  }
  slow.join();
  EXPECT_TRUE(refused) << "the slow client was not dropped";
}

// The MBAP length counts the unit id and the PDU: 2 to 254. Anything else cannot be a request
// and its end cannot be found; libmodbus ignored it and parsed the PDU regardless.
TEST_F(ModbusServerWithBystander, AnImpossibleLengthDropsTheClient) {
  for (const std::uint8_t length_high : {0x00, 0x01}) {
    RawConnection raw(output.port());
    const std::uint8_t length_low = length_high == 0 ? 1 : 0xFF;  // 1, 511
    raw.send({0x00, 0x09, 0x00, 0x00, length_high, length_low, 0x01, 0x04, 0x00, 0x10, 0x00, 0x01});
    EXPECT_TRUE(raw.closed_within(5s)) << "length " << (length_high << 8 | length_low);
  }
  EXPECT_EQ(read_input(bystander.get(), map::kFirstChannel, 1)[0], 300);
}

TEST(ModbusServer, StopsPromptly) {
  DriveControl control;
  auto output = std::make_unique<ModbusServerOutput>(tcp_server_options(), kChannels, control);
  const ModbusContext master = tcp_master(output->port());
  RawConnection stalled(output->port());
  stalled.send({0x00, 0x04, 0x00, 0x00, 0x00, 0x06, 0x01, 0x10, 0x00});  // the server sits in its byte timeout
  std::this_thread::sleep_for(10ms);
  const auto start = std::chrono::steady_clock::now();
  output.reset();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 100ms);
}

// ---------------------------------------------------------------- with the pipeline

std::unique_ptr<FrameProcessor> make_processor() {
  static const MorphableModel model = load_model_file(kModel);
  return std::make_unique<FrameProcessor>(model, kDefaultLandmarkSet, FitSettings{}, test::shared_predictor());
}

/// The pipeline on the talking-face clip at its recorded frame rate, with the server output.
class PipelineWithServer {
 public:
  PipelineWithServer()
      : pipeline_(
            std::make_unique<SimulatedCamera>(SimulatedCameraOptions{.input = kClip, .real_time = true, .loop = true}),
            make_processor(), settings(), control_),
        output_(tcp_server_options(), kChannels, control_) {
    pipeline_.add_output(output_);
    pipeline_.start();
  }

  Pipeline& pipeline() { return pipeline_; }
  ModbusServerOutput& output() { return output_; }

  /// Processed frames per second over `interval`.
  double processed_rate(std::chrono::milliseconds interval) {
    const std::uint64_t before = pipeline_.stats().processed;
    std::this_thread::sleep_for(interval);
    return static_cast<double>(pipeline_.stats().processed - before) / std::chrono::duration<double>(interval).count();
  }

 private:
  static PipelineSettings settings() {
    PipelineSettings settings;
    settings.channels = kChannels;
    settings.safety.ease_ns = 100'000'000;
    return settings;
  }

  // Each after what its threads use: destroyed in the safe order.
  DriveControl control_;
  Pipeline pipeline_;
  ModbusServerOutput output_;
};

class ModbusPipelineTest : public ::testing::Test {
 protected:
  void SetUp() override { LIPDRIVE_REQUIRE_BUILT(kClip); }
};

TEST_F(ModbusPipelineTest, RegistersFollowTheMouthAndControlTheDrive) {
  PipelineWithServer running;
  const ModbusContext master = tcp_master(running.output().port());
  const auto status = [&] { return read_input(master.get(), map::kStatus, 1)[0]; };
  ASSERT_TRUE(wait_for([&] { return (status() & kStatusTracking) != 0; }, 30s)) << "tracking within 30 s";

  std::uint16_t lowest = 65535, highest = 0, first_heartbeat = read_input(master.get(), map::kHeartbeat, 1)[0];
  const auto moves = [&] {
    const std::uint16_t open = read_input(master.get(), map::kFirstChannel, 1)[0];
    lowest = std::min(lowest, open);
    highest = std::max(highest, open);
    return highest - lowest > 100;
  };
  EXPECT_TRUE(wait_for(moves, 10s)) << "the open channel follows the talking mouth: " << lowest << ".." << highest;
  EXPECT_NE(read_input(master.get(), map::kHeartbeat, 1)[0], first_heartbeat) << "the heartbeat ticks";
  ASSERT_TRUE(wait_for([&] { return read_input(master.get(), map::kFpsTenths, 1)[0] > 0; }, 3s));
  const auto registers = read_input(master.get(), 0, map::kFirstChannel);
  EXPECT_GT((registers[map::kLatencyUsHigh] << 16) | registers[map::kLatencyUsLow], 0);
  EXPECT_GT((registers[map::kSequenceHigh] << 16) | registers[map::kSequenceLow], 0);
  EXPECT_EQ(registers[map::kChannelCount], kChannelCount);
  EXPECT_TRUE(registers[map::kStatus] & kStatusOutputsEnabled);

  // An override shows in the pipeline's next drive frames and in the channel register.
  write_holding(master.get(), map::kFirstOverride, 777);
  DriveFrame drive;
  EXPECT_TRUE(wait_for([&] {
    running.pipeline().latest_drive(drive);
    return drive.values[0] == 777;
  }));
  EXPECT_TRUE(wait_for([&] { return read_input(master.get(), map::kFirstChannel, 1)[0] == 777; }));
  write_holding(master.get(), map::kFirstOverride, map::kNoOverride);

  // Output enable off: the drive reports it and goes to the fail-safe.
  write_holding(master.get(), map::kOutputEnable, 0);
  EXPECT_TRUE(wait_for([&] { return (status() & (kStatusOutputsEnabled | kStatusFailSafe)) == kStatusFailSafe; }));
  write_holding(master.get(), map::kOutputEnable, 1);
  EXPECT_TRUE(wait_for([&] { return (status() & kStatusOutputsEnabled) != 0; }));

  const std::uint32_t calibrations = running.pipeline().control().calibrate_requests;
  write_holding(master.get(), map::kCalibrate, 1);
  EXPECT_EQ(running.pipeline().control().calibrate_requests, calibrations + 1);
  write_holding(master.get(), map::kRecord, 1);
  EXPECT_EQ(running.pipeline().control().recording_request, 1);
}

TEST_F(ModbusPipelineTest, EightPollingClientsDoNotSlowThePipeline) {
  PipelineWithServer running;
  ASSERT_TRUE(wait_for([&] { return running.pipeline().stats().tracked > 10; }, 30s));
  const double quiet = running.processed_rate(3s);

  constexpr int kClients = 8;
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> reads{0}, failures{0};
  std::vector<std::thread> clients;
  for (int i = 0; i < kClients; ++i)
    clients.emplace_back([&] {
      const ModbusContext master = tcp_master(running.output().port());
      std::uint16_t registers[map::kFirstChannel + 2];
      while (!stop) {
        if (modbus_read_input_registers(master.get(), 0, map::kFirstChannel + kChannelCount, registers) ==
            map::kFirstChannel + kChannelCount)
          ++reads;
        else
          ++failures;
      }
    });
  const double loaded = running.processed_rate(10s);
  stop = true;
  for (auto& client : clients) client.join();

  const double requests_per_s = static_cast<double>(reads) / 10;
  std::printf("processed %.1f frames/s quiet, %.1f frames/s under %d clients polling %.0f requests/s\n", quiet, loaded,
              kClients, requests_per_s);
  EXPECT_EQ(failures, 0u);
  EXPECT_GT(requests_per_s, 500) << "the clients really were polling";
  EXPECT_GE(loaded, 0.8 * quiet);
}

// ---------------------------------------------------------------- client mode

/// A libmodbus TCP slave on a thread: 64 holding registers, one connection at a time; it can
/// stop answering (connections stay open, requests go unread) and start again.
class TestSlave {
 public:
  TestSlave() : context_(modbus_new_tcp("127.0.0.1", 0)), mapping_(modbus_mapping_new(0, 0, 64, 0)) {
    listen_fd_ = modbus_tcp_listen(context_.get(), 16);
    sockaddr_in bound{};
    socklen_t size = sizeof bound;
    EXPECT_EQ(::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &size), 0);
    port_ = ntohs(bound.sin_port);
    thread_ = std::thread([this] { serve(); });
  }
  ~TestSlave() {
    stop_ = true;
    thread_.join();
    modbus_set_socket(context_.get(), -1);
    ::close(listen_fd_);
    modbus_mapping_free(mapping_);
  }
  int port() const { return port_; }
  void set_answering(bool answering) { answering_ = answering; }
  std::uint16_t holding(int address) {
    std::lock_guard lock(mutex_);
    return mapping_->tab_registers[address];
  }

 private:
  void serve() {
    int client = -1;
    std::uint8_t query[MODBUS_TCP_MAX_ADU_LENGTH];
    while (!stop_) {
      if (!answering_) {
        std::this_thread::sleep_for(5ms);
        continue;
      }
      pollfd readable{client == -1 ? listen_fd_ : client, POLLIN, 0};
      if (::poll(&readable, 1, 20) != 1) continue;
      if (client == -1) {
        client = ::accept(listen_fd_, nullptr, nullptr);
        continue;
      }
      modbus_set_socket(context_.get(), client);
      const int length = modbus_receive(context_.get(), query);
      if (length > 0 && answering_) {  // a request read as it stopped answering goes unanswered too
        std::lock_guard lock(mutex_);
        modbus_reply(context_.get(), query, length, mapping_);
      } else if (length == -1) {
        ::close(client);
        client = -1;
      }
    }
    if (client != -1) ::close(client);
  }

  ModbusContext context_;
  modbus_mapping_t* mapping_;
  std::mutex mutex_;
  int listen_fd_ = -1, port_ = 0;
  std::atomic<bool> stop_{false}, answering_{true};
  std::thread thread_;
};

/// Publishes a frame every 5 ms, the first channel counting up, and times every publish().
class Feeder {
 public:
  explicit Feeder(Output& output)
      : thread_([this, &output] {
          for (std::uint32_t counter = 1; !stop_; ++counter) {
            DriveFrame frame = frame_with(counter, counter % 1000, 1234);
            frame.sequence = counter;
            const std::int64_t start = monotonic_ns();
            output.publish(frame);
            slowest_ns_ = std::max<std::int64_t>(slowest_ns_, monotonic_ns() - start);
            std::this_thread::sleep_for(5ms);
          }
        }) {}
  ~Feeder() {
    stop_ = true;
    thread_.join();
  }
  std::int64_t slowest_publish_ns() const { return slowest_ns_; }

 private:
  std::atomic<bool> stop_{false};
  std::atomic<std::int64_t> slowest_ns_{0};
  std::thread thread_;
};

TEST(ModbusClient, WritesChannelsAndRidesOutADeadSlave) {
  TestSlave slave;
  ModbusClientOptions options;
  options.link.port = slave.port();
  options.channels = {"width", "open"};
  options.first_register = 10;
  options.rate_hz = 50;
  options.timeout_ms = 100;
  options.max_backoff_ms = 400;
  ModbusClientOutput output(options, kChannels);
  EXPECT_THAT(output.describe(), HasSubstr("registers 10..11"));
  Feeder feeder(output);

  ASSERT_TRUE(wait_for([&] { return slave.holding(10) == 1234 && slave.holding(11) > 0 && output.sends_ok() > 10; }))
      << "the channels arrive in the configured order";
  EXPECT_TRUE(output.healthy());
  EXPECT_EQ(output.sends_failed(), 0u);
  // At most rate_hz: 0.5 s of feeding at 200 frames/s gives about 25 writes.
  const std::uint64_t ok_before = output.sends_ok();
  std::this_thread::sleep_for(500ms);
  EXPECT_LE(output.sends_ok() - ok_before, 30u);
  EXPECT_GT(output.wire_latency()->count(), 0u);

  slave.set_answering(false);
  EXPECT_TRUE(wait_for([&] { return output.sends_failed() >= 3 && !output.healthy(); }))
      << "failed " << output.sends_failed();
  const std::uint16_t stale = slave.holding(11);

  slave.set_answering(true);
  const std::uint64_t ok_after_outage = output.sends_ok();
  EXPECT_TRUE(wait_for([&] { return output.sends_ok() > ok_after_outage + 5 && output.healthy(); }));
  EXPECT_TRUE(wait_for([&] { return slave.holding(11) != stale; })) << "new values arrive again";
  EXPECT_LT(feeder.slowest_publish_ns(), 5'000'000) << "publish() never waits for the slave";
  std::printf("capture->wire latency median %.2f ms, p99 %.2f ms over %llu frames\n",
              output.wire_latency()->quantile_ms(0.5), output.wire_latency()->quantile_ms(0.99),
              static_cast<unsigned long long>(output.wire_latency()->count()));
}

// A slave that stopped answering does not hold the stop for one more request's timeout: the
// neutral pose is not tried on a link whose last request went unanswered (said in the log), and
// the stop waits at most for a request already on its way.
TEST(ModbusClient, AStopWithASilentSlaveWaitsForNoFurtherTimeout) {
  const testing::CapturedLog log;
  TestSlave slave;
  ModbusClientOptions options;
  options.link.port = slave.port();
  options.timeout_ms = 2000;
  options.max_backoff_ms = 10'000;
  auto output = std::make_unique<ModbusClientOutput>(options, kChannels);
  output->publish(frame_with(1, 500, 1234));
  ASSERT_TRUE(wait_for([&] { return output->sends_ok() > 0; }));
  slave.set_answering(false);
  std::uint32_t counter = 2;
  ASSERT_TRUE(wait_for(
      [&] {
        output->publish(frame_with(counter++, 700, 1234));  // new values, until one goes unanswered
        return output->sends_failed() > 0;
      },
      30s));
  output->publish(frame_with(counter, 0, 0));  // the neutral pose
  const auto start = std::chrono::steady_clock::now();
  output.reset();
  const auto stop_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(stop_ms, options.timeout_ms + 1000) << "a stop waited for another request";
  const std::vector<std::string> warnings = log.messages(spdlog::level::warn);
  EXPECT_TRUE(std::ranges::any_of(
      warnings, [](const std::string& m) { return m.find("the neutral pose was not sent") != std::string::npos; }));
}

// A stop waits for a request on its way, but no output starts another once the daemon stops:
// asked together (as the daemon asks its outputs), two clients of slaves that stopped answering
// stop in one request's timeout. One by one, the second client retried (its first back-off is
// 100 ms) while the first was being joined, and the stop took two (two Modbus clients would
// outlast the service's 3 s stop).
TEST(ModbusClient, ClientsAskedToStopTogetherStartNoFurtherRequest) {
  TestSlave first_slave, second_slave;
  ModbusClientOptions options;
  options.rate_hz = 200;
  options.timeout_ms = 1000;
  std::vector<std::unique_ptr<ModbusClientOutput>> outputs;
  for (const TestSlave* slave : {&first_slave, &second_slave}) {
    options.link.port = slave->port();
    outputs.push_back(std::make_unique<ModbusClientOutput>(options, kChannels));
    outputs.back()->publish(frame_with(1, 500, 1234));
  }
  ASSERT_TRUE(wait_for([&] { return outputs[0]->sends_ok() > 0 && outputs[1]->sends_ok() > 0; }));
  // The second slave falls silent first: its client's request times out 150 ms before the
  // first's, and one back-off later it would retry, while the first is still being waited for.
  second_slave.set_answering(false);
  outputs[1]->publish(frame_with(2, 0, 0));
  std::this_thread::sleep_for(150ms);
  first_slave.set_answering(false);
  outputs[0]->publish(frame_with(2, 0, 0));  // the neutral pose
  std::this_thread::sleep_for(20ms);
  const auto start = std::chrono::steady_clock::now();
  for (const auto& output : outputs) output->request_stop();
  outputs.clear();
  const auto stop_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(stop_ms, options.timeout_ms + 500) << "a client started another request after the stop";
}

TEST(ModbusClient, UnknownChannelIsNamed) {
  ModbusClientOptions options;
  options.channels = {"open", "jaw"};
  try {
    ModbusClientOutput output(options, kChannels);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    EXPECT_THAT(error.what(), HasSubstr("'jaw'"));
  }
}

}  // namespace
}  // namespace lipdrive
