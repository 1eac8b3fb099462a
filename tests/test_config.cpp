// The daemon's configuration file: the reference file is valid, and every kind of mistake
// is reported with the file, the key and the reason.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "daemon_process.hpp"
#include "firmware_app/config/config.hpp"
#include "fixture_paths.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;
using ::testing::Not;

using test::kClip;
using test::kModel;

class ConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lipdrive_test_config_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    file_ = dir_ / "lipdrive.toml";
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// A valid file with the built model and clip, plus `camera` lines and other sections.
  void write(const std::string& camera, const std::string& rest = "") const {
    write_text(fmt::format("[model]\nfile = \"{}\"\n\n[camera]\ninput = \"{}\"\n{}\n\n{}\n", kModel.string(),
                           kClip.string(), camera, rest));
  }
  void write_text(const std::string& text) const { std::ofstream(file_) << text; }

  /// The ConfigError message load_config throws for the file as written.
  std::string error() const {
    try {
      load_config(file_);
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.exit_code(), kExitConfig);
      return e.what();
    }
    ADD_FAILURE() << "no ConfigError for " << file_;
    return {};
  }

  fs::path dir_, file_;
};

TEST_F(ConfigTest, ValidFileLoadsWithItsValues) {
  write(
      "type = \"sim\"\nreal_time = false\nfps = 30\nrotation = 270\n[camera.controls]\nexposure_us = 4000\n"
      "power_line_hz = 50\nkeep_frame_rate = false\n[camera.faults]\ndrop_every = 7\nstall_ms = 20",
      "[log]\nlevel = \"debug\"\n[recording]\nflush_interval_ms = 250\n[status]\nprint_interval_ms = 0\n"
      "[scheduling]\nrealtime_priority = 20\ncpu_latency_us = 0\nwarm_ahead_us = 0\n[tracker]\nmin_face_px = 240");
  const Config config = load_config(file_);
  EXPECT_EQ(config.tracker.settings.min_face_px, 240);
  EXPECT_EQ(config.model.file, kModel);
  EXPECT_EQ(config.model.landmark_set, LandmarkSet::F5) << "the ICT head's, with the jaw line";
  EXPECT_EQ(config.model.auto_identity_frames, 20);
  EXPECT_EQ(config.camera.sim.input, kClip);
  EXPECT_FALSE(config.camera.sim.real_time);
  EXPECT_TRUE(config.camera.sim.loop);
  EXPECT_EQ(config.camera.v4l2.frame_rate, 30);
  EXPECT_EQ(config.camera.sim.faults.drop_every, 7);
  EXPECT_EQ(config.camera.rotation, Rotation::k270);
  EXPECT_EQ(config.camera.v4l2.controls.exposure_us, 4000);
  EXPECT_EQ(config.camera.v4l2.controls.gain, -1) << "as the camera sets it";
  EXPECT_EQ(config.camera.v4l2.controls.power_line_hz, 50);
  EXPECT_FALSE(config.camera.v4l2.controls.keep_frame_rate);
  EXPECT_EQ(config.camera.sim.faults.stall, std::chrono::milliseconds(20));
  EXPECT_EQ(config.log_level, spdlog::level::debug);
  EXPECT_EQ(config.recording.flush_interval_ms, 250);
  EXPECT_EQ(config.status.print_interval_ms, 0);
  EXPECT_EQ(config.scheduling.realtime_priority, 20);
  EXPECT_EQ(config.scheduling.cpu_latency_us, 0);
  EXPECT_EQ(config.scheduling.warm_ahead_us, 0);
}

TEST_F(ConfigTest, UnknownKeysAreRejectedAnywhere) {
  write("fpz = 30");
  EXPECT_THAT(error(), AllOf(HasSubstr(file_.string() + ": key camera.fpz: unknown key")));
  write("", "[camera.faults]\ndrop_evry = 2");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ": key camera.faults.drop_evry: unknown key"));
  write("", "[ouputs]\nmodbus = true");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ": key ouputs: unknown key"));
  write("", "[outputs]\nmodbus = true");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ": key outputs.modbus: unknown key"));
}

TEST_F(ConfigTest, WrongTypesNameTheExpectedType) {
  write("fps = \"60\"");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ": key camera.fps: must be an integer, got a string"));
  write("real_time = 1");
  EXPECT_THAT(error(), HasSubstr("key camera.real_time: must be true or false, got an integer"));
  write("", "[status]\nprint_interval_ms = 1.5");
  EXPECT_THAT(error(), HasSubstr("key status.print_interval_ms: must be an integer, got a number"));
  write("[camera.controls]\nkeep_frame_rate = 0");
  EXPECT_THAT(error(), HasSubstr("key camera.controls.keep_frame_rate: must be true or false, got an integer"));
  write("faults = 3");
  EXPECT_THAT(error(), HasSubstr("key camera.faults: must be a table, got an integer"));
}

TEST_F(ConfigTest, OutOfRangeValuesNameTheRange) {
  write("fps = 500");
  EXPECT_EQ(error(), file_.string() + ": key camera.fps: must be between 1 and 240, got 500");
  write("", "[log]\nlevel = \"loud\"");
  EXPECT_THAT(error(), HasSubstr("key log.level: must be one of trace, debug, info, warn, error, got \"loud\""));
  write("[camera.controls]\npower_line_hz = 55");
  EXPECT_THAT(error(), HasSubstr("key camera.controls.power_line_hz: must be -1, 0, 50 or 60, got 55"));
  write("rotation = 45");
  EXPECT_THAT(error(), HasSubstr("key camera.rotation: 45 is not a quarter turn: 0, 90, 180 or 270 (degrees clockwise)"));
  write("", fmt::format("[side_camera]\nenabled = true\ninput = \"{}\"\nrotation = 360", kClip.string()));
  EXPECT_THAT(error(), HasSubstr("key side_camera.rotation: must be between 0 and 270, got 360"));
  write("format = \"RGB3\"");
  EXPECT_THAT(error(), HasSubstr("key camera.format: unknown pixel format 'RGB3'"));
  write("", "[recording]\nflush_interval_ms = 0");
  EXPECT_THAT(error(), HasSubstr("key recording.flush_interval_ms: must be between 10 and 60000, got 0"));
  write("", "[scheduling]\nrealtime_priority = 100");
  EXPECT_THAT(error(), HasSubstr("key scheduling.realtime_priority: must be between 0 and 99, got 100"));
  write("", "[scheduling]\ncpu_latency_us = 20000");
  EXPECT_THAT(error(), HasSubstr("key scheduling.cpu_latency_us: must be between -1 and 10000, got 20000"));
  write("", "[scheduling]\nwarm_ahead_us = -5");
  EXPECT_THAT(error(), HasSubstr("key scheduling.warm_ahead_us: must be between 0 and 100000, got -5"));
  write("", "[tracker]\nmin_face_px = 40");
  EXPECT_THAT(error(), HasSubstr("key tracker.min_face_px: must be between 80 and 4096, got 40"));
  write_text(fmt::format("[model]\nfile = \"{}\"\nauto_identity_frames = -1\n", kModel.string()));
  EXPECT_THAT(error(), HasSubstr("key model.auto_identity_frames: must be between 0 and 3600, got -1"));
}

TEST_F(ConfigTest, MissingFilesAreNamed) {
  const fs::path missing = dir_ / "missing.lpm";
  write_text(fmt::format("[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n", missing.string(), kClip.string()));
  EXPECT_EQ(error(), fmt::format("{}: key model.file: no such model file: {}", file_.string(), missing.string()));

  write("", fmt::format("[tracker]\npredictor = \"{}\"", (dir_ / "missing.dat").string()));
  EXPECT_THAT(error(), HasSubstr("key tracker.predictor: no such predictor file: " + (dir_ / "missing.dat").string()));

  write_text(fmt::format("[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n", kModel.string(),
                         (dir_ / "missing.avi").string()));
  EXPECT_THAT(error(), HasSubstr("key camera.input: no such file or folder: " + (dir_ / "missing.avi").string()));
}

TEST_F(ConfigTest, CamerasMustExistOnlyWhereTheyAreUsed) {
  // The rig's file: its cameras are not on the machine that processes recordings, and the
  // daemon waits for a camera that is not there yet (a USB camera enumerated after it started
  // at boot); calibrate on the camera needs it now.
  const fs::path missing = dir_ / "missing.avi";
  write_text(
      fmt::format("[model]\nfile = \"{}\"\n[camera]\ntype = \"v4l2\"\ndevice = \"/dev/video-lipdrive-missing\"\n"
                  "[side_camera]\nenabled = true\ninput = \"{}\"\n",
                  kModel.string(), missing.string()));
  for (const ConfigUse use : {ConfigUse::kOffline, ConfigUse::kCalibrateInput})
    EXPECT_EQ(load_config(file_, use).camera.v4l2.device, "/dev/video-lipdrive-missing");
  const auto calibrate_error = [this] {
    try {
      load_config(file_, ConfigUse::kCalibrateCamera);
      ADD_FAILURE() << "calibrate on the camera needs the camera";
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_THAT(calibrate_error(), HasSubstr("key camera.device: no such device: /dev/video-lipdrive-missing"));
  // A name without a slash is the camera's under /dev/v4l/by-id/ (drivers/v4l2_camera.hpp).
  write("type = \"v4l2\"\ndevice = \"usb-lipdrive-missing-video-index0\"");
  EXPECT_THAT(calibrate_error(),
              HasSubstr("key camera.device: no such device: /dev/v4l/by-id/usb-lipdrive-missing-video-index0"));
  EXPECT_EQ(load_config(file_, ConfigUse::kDaemon).camera.v4l2.device, "usb-lipdrive-missing-video-index0");
  write("", fmt::format("[side_camera]\nenabled = true\ninput = \"{}\"", missing.string()));
  EXPECT_THAT(error(), HasSubstr("key side_camera.input: no such file or folder: " + missing.string()));
  EXPECT_TRUE(load_config(file_, ConfigUse::kOffline).side_camera);
  // Every other key is checked in every use.
  write("type = \"v4l2\"\ndevice = \"/dev/video-lipdrive-missing\"\nfps = 500");
  try {
    load_config(file_, ConfigUse::kOffline);
    ADD_FAILURE() << "an offline use still checks the keys";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("key camera.fps: must be between 1 and 240, got 500"));
  }
}

TEST_F(ConfigTest, VoiceKeysLoadAndMistakesNameTheKey) {
  const fs::path model = dir_ / "performer.lpv";
  std::ofstream(model) << "not read when the configuration loads";
  write("", fmt::format("[voice]\nenabled = true\nmodel = \"{}\"\ncrossfade_ms = 100\naudio_timeout_ms = 300\n",
                        model.string()));
  const Config config = load_config(file_);
  EXPECT_TRUE(config.voice.enabled);
  EXPECT_EQ(config.voice.model, model);
  EXPECT_EQ(config.voice.input, Config::Voice::Input::kSim);
  EXPECT_EQ(config.voice.alsa.sample_rate, 16000);
  EXPECT_EQ(config.voice.alsa.period_frames, 160);
  EXPECT_EQ(config.voice.crossfade_ms, 100);
  EXPECT_EQ(config.voice.audio_timeout_ms, 300);

  write("", "[voice]\nenabled = true\n");
  EXPECT_EQ(error(),
            file_.string() + ": key voice.model: must name the performer's voice model (.lpv, `lipdrive voice train`)");
  write("", fmt::format("[voice]\nenabled = true\nmodel = \"{}\"", (dir_ / "missing.lpv").string()));
  EXPECT_THAT(error(), HasSubstr("key voice.model: no such voice model file: " + (dir_ / "missing.lpv").string()));
  write("", "[voice]\nloudness = 3");
  EXPECT_THAT(error(), HasSubstr("key voice.loudness: unknown key"));
  write("", "[voice]\ninput = \"usb\"");
  EXPECT_THAT(error(), HasSubstr("key voice.input: must be one of sim, alsa, got \"usb\""));
  write("", "[voice]\ncrossfade_ms = 5000");
  EXPECT_THAT(error(), HasSubstr("key voice.crossfade_ms: must be between 0 and 2000, got 5000"));
  write("", "[voice]\nsample_rate = 4000");
  EXPECT_THAT(error(), HasSubstr("key voice.sample_rate: must be between 8000 and 48000, got 4000"));
  write("", "[voice]\ninput = \"alsa\"\ndevice = \"\"");
  EXPECT_THAT(error(), HasSubstr("key voice.device: must name an ALSA capture device"));
  // The clip's sound plays at its own rate: a replay at another rate cannot keep in step.
  write("replay_fps = 60", fmt::format("[voice]\nenabled = true\nmodel = \"{}\"", model.string()));
  EXPECT_THAT(error(), HasSubstr("key voice.input: \"sim\" plays the clip's sound at its own rate"));
}

TEST_F(ConfigTest, AnEmptyRecordingFolderIsRefused) {
  write("", "[recording]\ndir = \"\"");
  EXPECT_EQ(error(), file_.string() + ": key recording.dir: must name the folder takes are written to");
}

TEST_F(ConfigTest, SyntaxErrorsNameTheLine) {
  write_text("[camera]\nfps = = 3\n");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ":2:"));
}

test::CommandRun run_lipdrive(const std::string& args) {
  return test::run_command(std::string(test::kLipdrive) + " " + args);
}

// A device, a folder or a FIFO where a file belongs: the daemon would read /dev/zero as a model
// without end, or block its start on a FIFO given as the clip until something wrote to it.
TEST_F(ConfigTest, PathsMustNameWhatTheKeyReads) {
  const fs::path fifo = dir_ / "clip.fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  write_text(fmt::format("[model]\nfile = \"/dev/zero\"\n[camera]\ninput = \"{}\"\n", kClip.string()));
  EXPECT_EQ(error(), file_.string() + ": key model.file: /dev/zero is a character device, not a model file");
  write_text(fmt::format("[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n", dir_.string(), kClip.string()));
  EXPECT_EQ(error(),
            fmt::format("{}: key model.file: {} is a folder, not a model file", file_.string(), dir_.string()));
  write("", "[tracker]\npredictor = \"/dev/zero\"");
  EXPECT_THAT(error(), HasSubstr("key tracker.predictor: /dev/zero is a character device, not a predictor file"));
  write_text(fmt::format("[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n", kModel.string(), fifo.string()));
  EXPECT_THAT(error(), HasSubstr(fmt::format("key camera.input: {} is a FIFO, not a file or folder", fifo.string())));
  write("", "[recording]\ndir = \"/dev/zero\"");
  EXPECT_THAT(error(), HasSubstr("key recording.dir: /dev/zero is a character device, not a folder"));
  // A folder of images replays; a folder of takes not made yet is made by the first take.
  write_text(fmt::format("[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n[recording]\ndir = \"{}\"\n",
                         kModel.string(), dir_.string(), (dir_ / "takes").string()));
  EXPECT_NO_THROW(load_config(file_));
  // A camera's device must be one: calibrate on the camera opens it.
  write("type = \"v4l2\"\ndevice = \"/dev/null\"");
  EXPECT_NO_THROW(load_config(file_, ConfigUse::kCalibrateCamera));
  write(fmt::format("type = \"v4l2\"\ndevice = \"{}\"", kClip.string()));
  try {
    load_config(file_, ConfigUse::kCalibrateCamera);
    ADD_FAILURE() << "a file is not a camera";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr(fmt::format("key camera.device: {} is a file, not a device", kClip.string())));
  }
  // The daemon refuses it at once instead of hanging on the FIFO (which no signal would end).
  write_text(fmt::format("[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n", kModel.string(), fifo.string()));
  const test::CommandRun run =
      test::run_command("timeout 30 " + std::string(test::kLipdrive) + " run --frames 1 --config " + file_.string());
  EXPECT_EQ(run.exit_code, 78) << run.output;
}

constexpr const char* kJawChannel =
    "[[channels]]\nname = \"jaw\"\nsignal = \"open\"\nout_min = 1000\nout_max = 2000\n"
    "neutral = 1100\nmax_slew_per_s = 4000\n";

TEST_F(ConfigTest, ChannelsAndOutputsLoad) {
  write("", fmt::format("{}[[channels]]\nname = \"smile\"\nsignal = \"viseme_Eee\"\ninvert = true\n"
                        "smoothing = {{ min_cutoff_hz = 2.5, beta = 0.4 }}\n"
                        "[safety]\nhold_ms = 100\nease_ms = 300\n"
                        "[[outputs.modbus_server]]\nport = 15020\n"
                        "[[outputs.modbus_server]]\ntransport = \"rtu\"\ndevice = \"/dev/ttyS1\"\nbaud = 19200\n"
                        "parity = \"E\"\nunit_id = 7\n"
                        "[[outputs.serial]]\nmode = \"maestro\"\nservos = {{ jaw = 3 }}\n"
                        "[[outputs.modbus_client]]\nchannels = [\"smile\", \"jaw\"]\nrate_hz = 20\n"
                        "[[channels]]\nname = \"pucker\"\nsignal = \"arkit_mouthPucker\"\n",
                        kJawChannel));
  const Config config = load_config(file_);
  ASSERT_EQ(config.channels.size(), 3u);
  EXPECT_EQ(config.channels[2].signal, arkit_signal(*arkit_index("mouthPucker")));
  EXPECT_EQ(config.channels[0].name, "jaw");
  EXPECT_EQ(config.channels[0].out_min, 1000);
  EXPECT_EQ(config.channels[0].neutral, 1100);
  EXPECT_EQ(config.channels[0].max_slew_per_s, 4000);
  EXPECT_EQ(config.channels[1].signal, viseme_signal(5));
  EXPECT_TRUE(config.channels[1].invert);
  EXPECT_FALSE(config.channels[0].smoothed);
  EXPECT_TRUE(config.channels[1].smoothed);
  EXPECT_EQ(config.channels[1].smoothing.min_cutoff_hz, 2.5);
  EXPECT_EQ(config.channels[1].smoothing.beta, 0.4);
  EXPECT_EQ(config.safety.hold_ns, 100'000'000);
  EXPECT_EQ(config.safety.ease_ns, 300'000'000);
  ASSERT_EQ(config.outputs.modbus_servers.size(), 2u);
  EXPECT_EQ(config.outputs.modbus_servers[0].link.port, 15020);
  EXPECT_EQ(config.outputs.modbus_servers[1].link.transport, ModbusEndpoint::Transport::kRtu);
  EXPECT_EQ(config.outputs.modbus_servers[1].link.line.parity, 'E');
  EXPECT_EQ(config.outputs.modbus_servers[1].link.unit_id, 7);
  ASSERT_EQ(config.outputs.serial.size(), 1u);
  EXPECT_EQ(config.outputs.serial[0].mode, SerialOutputOptions::Mode::kMaestro);
  ASSERT_EQ(config.outputs.serial[0].servos.size(), 1u);
  EXPECT_EQ(config.outputs.serial[0].servos[0].servo, 3);
  ASSERT_EQ(config.outputs.modbus_clients.size(), 1u);
  EXPECT_EQ(config.outputs.modbus_clients[0].channels, (std::vector<std::string>{"smile", "jaw"}));
}

TEST_F(ConfigTest, ChannelAndOutputMistakesNameTheKey) {
  const std::string at = file_.string() + ": key ";
  write("", "[[channels]]\nname = \"jaw\"\nsignal = \"jaw_open\"");
  EXPECT_THAT(error(), AllOf(HasSubstr(at + "channels[0].signal: unknown signal \"jaw_open\"")));
  write("", "[[channels]]\nsignal = \"open\"");
  EXPECT_THAT(error(), HasSubstr(at + "channels[0].name: every channel needs a name"));
  write("", "[[channels]]\nname = \"jaw\"\nout_min = 10\nout_max = 20\nneutral = 30");
  EXPECT_THAT(error(), HasSubstr(at + "channels[0].neutral: must lie between out_min 10 and out_max 20"));
  write("", std::string(kJawChannel) + kJawChannel);
  EXPECT_THAT(error(), HasSubstr(at + "channels[1].name: \"jaw\" is already a channel"));
  write("", std::string(kJawChannel) + "[[outputs.serial]]\nchannels = [\"lips\"]");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.serial[0].channels: no channel named \"lips\""));
  write("", std::string(kJawChannel) + "[[outputs.serial]]\nmode = \"maestro\"\nservos = { jaw = 24 }");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.serial[0].servos.jaw: must be between 0 and 23, got 24"));
  write("", std::string(kJawChannel) + "[[outputs.serial]]\nmode = \"maestro\"");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.serial[0].servos: maestro mode needs servos"));
  write("", "[[outputs.modbus_server]]\nport = 70000");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.modbus_server[0].port: must be between 1 and 65535, got 70000"));
  write("", "[outputs]\nmodbus_server = 1");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.modbus_server: must be an array of tables"));
  write("", "[[outputs.serial]]\ndevice = \"\"");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.serial[0].device: serial device is empty"));
  write("", "[[outputs.serial]]\nbaud = 12345");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.serial[0].baud: serial baud 12345 is not supported"));
  write("",
        std::string(kJawChannel) + "[[channels]]\nname = \"lips\"\n[[outputs.modbus_client]]\nfirst_register = 65535");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.modbus_client[0].first_register: 2 channels from register 65535 run "
                                      "past the last register, 65535"));
  write("", std::string(kJawChannel) + "[[outputs.modbus_client]]\nfirst_register = 65535");
  EXPECT_EQ(load_config(file_).outputs.modbus_clients[0].first_register, 65535) << "one channel fits";
  write("", std::string(kJawChannel) + "[[outputs.modbus_client]]\ntimeout_ms = 5000");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.modbus_client[0].timeout_ms: must be between 1 and 2000, got 5000"));
  write("", "[[outputs.modbus_server]]\nparity = \"X\"");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.modbus_server[0].parity: must be one of N, E, O"));
  write("", "[performer]\nname = \"nobody\"\nprofiles_dir = \"" + dir_.string() + "\"");
  EXPECT_THAT(error(), HasSubstr(at + "performer.name: no such performer profile"));
  write("", "[performer]\nname = \"../etc/passwd\"");
  EXPECT_THAT(error(), HasSubstr(at + "performer.name: performer name"));
}

// libmodbus takes numeric IPv4 addresses only: "localhost" passed, then the server listened on
// 255.255.255.255 and the client never reached its slave. A name is resolved at load.
TEST_F(ConfigTest, ModbusHostNamesResolveToANumericAddressOrNameTheKey) {
  const std::string at = file_.string() + ": key ";
  write("", std::string(kJawChannel) +
                "[[outputs.modbus_server]]\naddress = \"localhost\"\n"
                "[[outputs.modbus_client]]\naddress = \"localhost\"\nport = 1503\n"
                "[[outputs.modbus_server]]\ntransport = \"rtu\"\naddress = \"not looked up for rtu.invalid\"\n");
  const Config config = load_config(file_);
  EXPECT_EQ(config.outputs.modbus_servers[0].link.address, "127.0.0.1");
  EXPECT_EQ(config.outputs.modbus_clients[0].link.address, "127.0.0.1");
  write("", "[[outputs.modbus_server]]\naddress = \"no-such-host.invalid\"");
  EXPECT_THAT(error(),
              HasSubstr(at + "outputs.modbus_server[0].address: host \"no-such-host.invalid\" does not resolve"));
  write("", std::string(kJawChannel) + "[[outputs.modbus_client]]\naddress = \"::1\"");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.modbus_client[0].address: host \"::1\" has no IPv4 address"));
}

TEST_F(ConfigTest, DmxFootprintMistakesNameTheKey) {
  const std::string at = file_.string() + ": key ";
  const std::string channels = std::string(kJawChannel) + "[[channels]]\nname = \"lips\"\n";
  write("", channels +
                "[[outputs.dmx]]\nuniverse = 1\n[[outputs.dmx.channels]]\nname = \"jaw\"\nbits = 16\n"
                "[[outputs.dmx.channels]]\nname = \"lips\"\n");
  const Config config = load_config(file_);
  ASSERT_EQ(config.outputs.dmx.size(), 1u);
  const auto& footprint = config.outputs.dmx[0].footprint;
  ASSERT_EQ(footprint.size(), 2u);
  EXPECT_EQ(footprint[0].address, 1);
  EXPECT_TRUE(footprint[0].sixteen_bit);
  EXPECT_EQ(footprint[1].address, 3) << "the next channel follows the 16-bit one's fine slot";
  EXPECT_EQ(footprint[1].channel_index, 1);

  write("", channels + "[[outputs.dmx]]\nuniverse = 0\n[[outputs.dmx.channels]]\nname = \"jaw\"\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[0].universe: must be between 1 and 63999, got 0"));
  write("", channels + "[[outputs.dmx]]\nuniverse = 64000\n[[outputs.dmx.channels]]\nname = \"jaw\"\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[0].universe: must be between 1 and 63999, got 64000"));
  write("", channels +
                "[[outputs.dmx]]\n[[outputs.dmx.channels]]\nname = \"jaw\"\nbits = 16\n"
                "[[outputs.dmx.channels]]\nname = \"lips\"\naddress = 2\n");
  EXPECT_THAT(error(), AllOf(HasSubstr(at + "outputs.dmx[0].channels[1].address: channel \"lips\" at address 2 "
                                            "collides with channel \"jaw\" (addresses 1..2)")));
  write("", channels +
                "[[outputs.dmx]]\n[[outputs.dmx.channels]]\nname = \"jaw\"\naddress = 5\n"
                "[[outputs.dmx]]\n[[outputs.dmx.channels]]\nname = \"lips\"\naddress = 5\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[1].channels[0].address: channel \"lips\" at address 5 collides"))
      << "two outputs on one universe";
  write("", channels + "[[outputs.dmx]]\nstart_address = 512\n[[outputs.dmx.channels]]\nname = \"jaw\"\nbits = 16\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[0].channels[0].address: a 16-bit channel needs two slots"));
  write("", channels + "[[outputs.dmx]]\n[[outputs.dmx.channels]]\nname = \"jaw\"\nbits = 12\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[0].channels[0].bits: must be 8 or 16, got 12"));
  write("", channels + "[[outputs.dmx]]\n[[outputs.dmx.channels]]\nname = \"teeth\"\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[0].channels[0].name: no channel named \"teeth\""));
  write("", channels + "[[outputs.dmx]]\nrate_hz = 60\n[[outputs.dmx.channels]]\nname = \"jaw\"\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[0].rate_hz: must be between 1 and 44, got 60"));
  write("", channels + "[[outputs.dmx]]\n");
  EXPECT_THAT(error(), HasSubstr(at + "outputs.dmx[0].channels: needs at least one"));
}

TEST_F(ConfigTest, ReferenceFileIsValid) {
  // The shipped file: default model and the default clip next to the binary.
  const fs::path reference = fs::path(test::kSourceDir) / "config" / "lipdrive.toml";
  const test::CommandRun run = run_lipdrive("check-config " + reference.string());
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_THAT(run.output, HasSubstr(reference.string() + ": ok"));
}

TEST_F(ConfigTest, TheMonitorIsOffUnlessTurnedOn) {
  write("");
  EXPECT_FALSE(load_config(file_).monitor.enabled) << "a file without [monitor] serves no page";
}

TEST_F(ConfigTest, CheckConfigExitsWithExConfig) {
  write("fps = 500");
  const test::CommandRun run = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(run.exit_code, 78) << run.output;
  EXPECT_THAT(run.output, HasSubstr(file_.string() + ": key camera.fps: must be between 1 and 240, got 500"));
  EXPECT_EQ(run_lipdrive("check-config " + (dir_ / "none.toml").string()).exit_code, 78);
  const test::CommandRun folder = run_lipdrive("check-config " + dir_.string());
  EXPECT_EQ(folder.exit_code, 78) << folder.output;
  EXPECT_THAT(folder.output, HasSubstr(dir_.string() + ": cannot read the file: not a regular file"));
  // A file cut to nothing, or to its comments: every default would drive nothing.
  write_text("# only a comment\n\n");
  const test::CommandRun empty = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(empty.exit_code, 78) << empty.output;
  EXPECT_THAT(empty.output, HasSubstr(file_.string() + ": the file holds no settings"));
  // Why a file cannot be read.
  const test::CommandRun missing = run_lipdrive("check-config " + (dir_ / "none.toml").string());
  EXPECT_THAT(missing.output, HasSubstr((dir_ / "none.toml").string() + ": cannot read the file: No such file"));
}

// At boot the name server may not answer yet: a host name that cannot be looked up *now* is not
// a mistake in the file. The daemon exits with EX_TEMPFAIL, which the unit restarts it on (it
// stops for good on 78, as for the name no server knows: ModbusHostNames... above). A network
// namespace of its own, with no interface up, is a machine whose network is not up yet.
TEST_F(ConfigTest, AHostLookedUpBeforeTheNetworkIsUpIsTriedAgainNotAMistake) {
  if (test::run_command("unshare -n true").exit_code != 0) GTEST_SKIP() << "unshare -n is not permitted here";
  const auto check_offline = [&] {
    return test::run_command("unshare -n " + std::string(test::kLipdrive) + " check-config " + file_.string());
  };
  write("", std::string(kJawChannel) + "[[outputs.osc]]\nhost = \"mixer.invalid\"\nchannels = [\"jaw\"]\n");
  const test::CommandRun booting = check_offline();
  EXPECT_EQ(booting.exit_code, 75) << booting.output;
  EXPECT_THAT(booting.output, HasSubstr(file_.string() + ": key outputs.osc[0].host: host \"mixer.invalid\" does not "
                                        "resolve: Temporary failure in name resolution; trying again"));
  // A numeric address needs no name server.
  write("", std::string(kJawChannel) + "[[outputs.osc]]\nhost = \"192.168.1.20\"\nchannels = [\"jaw\"]\n");
  const test::CommandRun numeric = check_offline();
  EXPECT_EQ(numeric.exit_code, 0) << numeric.output;
}

// check-config reads what the daemon reads before it starts, with the daemon's exit codes: a
// model, a predictor or a performer profile the daemon would stop on is not "ok".
TEST_F(ConfigTest, CheckConfigReadsTheFilesTheDaemonReads) {
  const fs::path damaged = dir_ / "damaged.lpm";
  std::ofstream(damaged) << "not a model";
  write_text(fmt::format("[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n", damaged.string(), kClip.string()));
  const test::CommandRun model = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(model.exit_code, 65) << model.output;
  EXPECT_THAT(model.output, HasSubstr(damaged.string() + ": not a lipdrive model"));
  const fs::path predictor_file = dir_ / "damaged.lpp";
  std::ofstream(predictor_file) << "not a predictor";
  write("", fmt::format("[tracker]\npredictor = \"{}\"\n", predictor_file.string()));
  const test::CommandRun predictor = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(predictor.exit_code, 65) << predictor.output;
  EXPECT_THAT(predictor.output, HasSubstr(predictor_file.string()));
  // A performer whose profile holds something no calibration writes.
  std::ofstream(dir_ / "ana.toml") << "open = \"wide\"\n";
  write("", fmt::format("[performer]\nname = \"ana\"\nprofiles_dir = \"{}\"\n", dir_.string()));
  const test::CommandRun profile = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(profile.exit_code, 65) << profile.output;
  EXPECT_THAT(profile.output, HasSubstr((dir_ / "ana.toml").string()));
  write("");
  const test::CommandRun nothing_driven = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(nothing_driven.exit_code, 0) << nothing_driven.output;
  EXPECT_THAT(nothing_driven.output, HasSubstr("no output is configured: the daemon would drive nothing"));
  write("", std::string(kJawChannel) + "[[outputs.osc]]\nhost = \"127.0.0.1\"\n");
  EXPECT_THAT(run_lipdrive("check-config " + file_.string()).output, Not(HasSubstr("no output")));
}

// A USB camera enumerated after the daemon started at boot: the daemon runs (the figure at
// neutral, the status saying why) until it appears, instead of stopping on a configuration error
// the service manager would not restart.
TEST_F(ConfigTest, TheDaemonWaitsForACameraNotThereYet) {
  write("type = \"v4l2\"\ndevice = \"/dev/video-lipdrive-missing\"", "[status]\nprint_interval_ms = 100\n");
  EXPECT_EQ(run_lipdrive("check-config " + file_.string()).exit_code, 0);
  test::DaemonProcess daemon(file_, dir_ / "daemon.log");
  EXPECT_TRUE(daemon.wait_for_log("0.0 fps, latency n/a, drive fail-safe, not tracked, dropped 0, camera disconnected"))
      << daemon.log();
  EXPECT_TRUE(daemon.running()) << daemon.log();
  EXPECT_THAT(daemon.log(), HasSubstr("/dev/video-lipdrive-missing: cannot open the device: No such file or directory; "
                                      "waiting for it"));
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(std::chrono::seconds(10)), 0) << daemon.log();
}

#ifdef LIPDRIVE_HAVE_LIBCAMERA
// The same for a CSI camera whose ISP is enumerated after the daemon started (this machine has
// none): the daemon waits, calibrate on the camera stops with the reason.
TEST_F(ConfigTest, TheDaemonWaitsForALibcameraCameraNotThereYetAndCalibrateDoesNot) {
  write("type = \"libcamera\"", "[status]\nprint_interval_ms = 100\n");
  test::DaemonProcess daemon(file_, dir_ / "daemon.log");
  EXPECT_TRUE(daemon.wait_for_log("0.0 fps, latency n/a, drive fail-safe, not tracked, dropped 0, camera disconnected"))
      << daemon.log();
  EXPECT_TRUE(daemon.running()) << daemon.log();
  EXPECT_THAT(daemon.log(), HasSubstr("libcamera: no cameras found; waiting for it"));
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(std::chrono::seconds(10)), 0) << daemon.log();
  const test::CommandRun live = run_lipdrive(
      fmt::format("calibrate --config {} --performer bob --out {}", file_.string(), (dir_ / "bob.toml").string()));
  EXPECT_EQ(live.exit_code, 78) << live.output;
  EXPECT_THAT(live.output, HasSubstr("key camera.type: libcamera: no cameras found"));
}
#endif

TEST_F(ConfigTest, RunRefusesANegativeFrameCount) {
  write("");
  // Under `timeout`: a count that wraps round runs until stopped.
  const test::CommandRun run =
      test::run_command(fmt::format("timeout 10 {} run --config {} --frames -1", test::kLipdrive, file_.string()));
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_NE(run.exit_code, 124) << "ran: " << run.output;
  EXPECT_THAT(run.output, HasSubstr("--frames: must not be negative"));
}

TEST_F(ConfigTest, CalibrateWritesTheProfileTheConfigurationNames) {
  // Every other command needs the named performer's profile; calibrate is what writes it.
  write("", fmt::format("[performer]\nname = \"alice\"\nprofiles_dir = \"{}\"", dir_.string()));
  EXPECT_THAT(error(), HasSubstr("key performer.name: no such performer profile"));
  const test::CommandRun run =
      run_lipdrive(fmt::format("calibrate --config {} --performer alice --input {}", file_.string(), kClip.string()));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(fs::exists(dir_ / "alice.toml"));
  EXPECT_EQ(load_config(file_).performer.name, "alice") << "the profile it names now exists";
}

TEST_F(ConfigTest, CalibrateRefusesAPerformerNameThatIsNotAPlainFileName) {
  // It was exit 1 (the same name in [performer] name is 78); with --out it was not checked at all.
  write("", fmt::format("[performer]\nprofiles_dir = \"{}\"", dir_.string()));
  for (const std::string& out : {std::string(), " --out " + (dir_ / "x.toml").string()}) {
    for (const char* name : {"../../x", "''", ".hidden"}) {
      const test::CommandRun run = run_lipdrive(
          fmt::format("calibrate --config {} --performer {} --input {}{}", file_.string(), name, kClip.string(), out));
      EXPECT_EQ(run.exit_code, 64) << name << out << ": " << run.output;
      EXPECT_THAT(run.output, HasSubstr("--performer: performer name"));
      EXPECT_THAT(run.output, HasSubstr("must be letters, digits, '-', '_' or '.', not starting with '.'"));
    }
  }
  EXPECT_FALSE(fs::exists(dir_ / "x.toml"));
}

TEST_F(ConfigTest, CalibrateOnTheConfiguredSimulatedCameraPlaysItOnce) {
  // The daemon loops the replayed clip; calibrating on it must end at the clip's end (the
  // timeout fails the test instead of hanging it).
  write("real_time = false\nloop = true");
  const test::CommandRun run = test::run_command(fmt::format("timeout 60 {} calibrate --config {} --performer carol --out {}",
                                                             test::kLipdrive, file_.string(),
                                                             (dir_ / "carol.toml").string()));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(fs::exists(dir_ / "carol.toml"));
}

TEST_F(ConfigTest, OfflineCommandsTakeTheRigsConfiguration) {
  // A camera this machine does not have: the recordings stand in for it.
  write("type = \"v4l2\"\ndevice = \"/dev/video-lipdrive-missing\"");
  const test::CommandRun process = run_lipdrive(
      fmt::format("process {} --config {} --out {}", kClip.string(), file_.string(), (dir_ / "measures.csv").string()));
  EXPECT_EQ(process.exit_code, 0) << process.output;
  const test::CommandRun calibrate =
      run_lipdrive(fmt::format("calibrate --config {} --performer bob --input {} --out {}", file_.string(),
                               kClip.string(), (dir_ / "bob.toml").string()));
  EXPECT_EQ(calibrate.exit_code, 0) << calibrate.output;
  const test::CommandRun live = run_lipdrive(
      fmt::format("calibrate --config {} --performer bob --out {}", file_.string(), (dir_ / "bob.toml").string()));
  EXPECT_EQ(live.exit_code, 78) << live.output;
  EXPECT_THAT(live.output, HasSubstr("key camera.device: no such device: /dev/video-lipdrive-missing"));
}

TEST_F(ConfigTest, CalibrateJudgesADamagedRecordingAsProcessDoes) {
  // The clip cut in half: process called it damaged (65) while calibrate wrote a profile from
  // the frames before the cut and exited 0.
  write("");
  const fs::path cut = dir_ / "cut.avi", profile = dir_ / "bob.toml";
  fs::copy_file(kClip, cut);
  fs::resize_file(cut, fs::file_size(kClip) / 2);
  const test::CommandRun process = run_lipdrive(
      fmt::format("process {} --config {} --out {}", cut.string(), file_.string(), (dir_ / "m.csv").string()));
  EXPECT_EQ(process.exit_code, 65) << process.output;
  const test::CommandRun calibrate = run_lipdrive(fmt::format(
      "calibrate --config {} --performer bob --input {} --out {}", file_.string(), cut.string(), profile.string()));
  EXPECT_EQ(calibrate.exit_code, 65) << calibrate.output;
  EXPECT_THAT(calibrate.output, HasSubstr("frames could not be decoded (named above)"));
  EXPECT_FALSE(fs::exists(profile)) << "no profile from a damaged recording";
}

TEST_F(ConfigTest, GpioInputBiasIsAutomaticUnlessNamed) {
  write("", "[outputs.gpio]\nenable_switch = \"GPIO24\"\n");
  EXPECT_EQ(load_config(file_).outputs.gpio.input_bias, GpioBias::kAuto) << "auto by default";
  for (const auto& [name, bias] : {std::pair{"auto", GpioBias::kAuto}, std::pair{"pull-up", GpioBias::kPullUp},
                                   std::pair{"pull-down", GpioBias::kPullDown},
                                   std::pair{"disable", GpioBias::kDisable}, std::pair{"as-is", GpioBias::kAsIs}}) {
    write("", fmt::format("[outputs.gpio]\ninput_bias = \"{}\"\n", name));
    EXPECT_EQ(load_config(file_).outputs.gpio.input_bias, bias) << name;
  }
  write("", "[outputs.gpio]\ninput_bias = \"up\"\n");
  EXPECT_THAT(error(), HasSubstr("key outputs.gpio.input_bias: must be one of auto, pull-up, pull-down, disable, "
                                 "as-is, got \"up\""));
}

TEST_F(ConfigTest, CheckConfigLooksUpTheGpioChip) {
  // This machine has no GPIO chip: the daemon would stop at start with exit 78, and so does
  // the check. Without [outputs.gpio] enabled the chip is not looked for.
  write("", "[outputs.gpio]\nenabled = true\nchip = \"gpiochip7\"\nenable_switch = \"GPIO24\"\n");
  const test::CommandRun run = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(run.exit_code, 78) << run.output;
  EXPECT_THAT(run.output, HasSubstr(file_.string() + ": key outputs.gpio: gpio chip gpiochip7: no such chip"));
  write("", "[outputs.gpio]\nenabled = false\nchip = \"gpiochip7\"\n");
  EXPECT_EQ(run_lipdrive("check-config " + file_.string()).exit_code, 0);
}

}  // namespace
}  // namespace lipdrive
