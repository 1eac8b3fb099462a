// The daemon's configuration file: the reference file is valid, and every kind of mistake
// is reported with the file, the key and the reason.
#include "firmware_app/config.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;

const fs::path kModel = fs::path(LIPDRIVE_MODEL_DIR) / "default.lpm";
const fs::path kClip = fs::path(LIPDRIVE_FIXTURE_DIR) / "talking_face.avi";

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
  write("type = \"sim\"\nreal_time = false\nfps = 30\n[camera.faults]\ndrop_every = 7\nstall_ms = 20",
        "[log]\nlevel = \"debug\"\n[recording]\nflush_interval_ms = 250\n[status]\nprint_interval_ms = 0");
  const Config config = load_config(file_);
  EXPECT_EQ(config.model.file, kModel);
  EXPECT_EQ(config.model.landmark_set, LandmarkSet::F4);
  EXPECT_EQ(config.camera.sim.input, kClip);
  EXPECT_FALSE(config.camera.sim.real_time);
  EXPECT_TRUE(config.camera.sim.loop);
  EXPECT_EQ(config.camera.v4l2.frame_rate, 30);
  EXPECT_EQ(config.camera.sim.faults.drop_every, 7);
  EXPECT_EQ(config.camera.sim.faults.stall, std::chrono::milliseconds(20));
  EXPECT_EQ(config.log_level, spdlog::level::debug);
  EXPECT_EQ(config.recording.flush_interval_ms, 250);
  EXPECT_EQ(config.status.print_interval_ms, 0);
}

TEST_F(ConfigTest, UnknownKeysAreRejectedAnywhere) {
  write("fpz = 30");
  EXPECT_THAT(error(), AllOf(HasSubstr(file_.string() + ": key camera.fpz: unknown key")));
  write("", "[camera.faults]\ndrop_evry = 2");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ": key camera.faults.drop_evry: unknown key"));
  write("", "[outputs]\nmodbus = true");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ": key outputs: unknown key"));
}

TEST_F(ConfigTest, WrongTypesNameTheExpectedType) {
  write("fps = \"60\"");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ": key camera.fps: must be an integer, got a string"));
  write("real_time = 1");
  EXPECT_THAT(error(), HasSubstr("key camera.real_time: must be true or false, got an integer"));
  write("", "[status]\nprint_interval_ms = 1.5");
  EXPECT_THAT(error(), HasSubstr("key status.print_interval_ms: must be an integer, got a number"));
  write("faults = 3");
  EXPECT_THAT(error(), HasSubstr("key camera.faults: must be a table, got an integer"));
}

TEST_F(ConfigTest, OutOfRangeValuesNameTheRange) {
  write("fps = 500");
  EXPECT_EQ(error(), file_.string() + ": key camera.fps: must be between 1 and 240, got 500");
  write("", "[log]\nlevel = \"loud\"");
  EXPECT_THAT(error(), HasSubstr("key log.level: must be one of trace, debug, info, warn, error, got \"loud\""));
  write("format = \"RGB3\"");
  EXPECT_THAT(error(), HasSubstr("key camera.format: unknown pixel format 'RGB3'"));
  write("", "[recording]\nflush_interval_ms = 0");
  EXPECT_THAT(error(), HasSubstr("key recording.flush_interval_ms: must be between 10 and 60000, got 0"));
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

  write("type = \"v4l2\"\ndevice = \"/dev/video-lipdrive-missing\"");
  EXPECT_THAT(error(), HasSubstr("key camera.device: no such device: /dev/video-lipdrive-missing"));
}

TEST_F(ConfigTest, SyntaxErrorsNameTheLine) {
  write_text("[camera]\nfps = = 3\n");
  EXPECT_THAT(error(), HasSubstr(file_.string() + ":2:"));
}

struct CommandRun {
  int exit_code = -1;
  std::string output;  // stdout and stderr
};

CommandRun run_lipdrive(const std::string& args) {
  const std::string command = std::string(LIPDRIVE_BINARY) + " " + args + " 2>&1";
  CommandRun run;
  FILE* pipe = ::popen(command.c_str(), "r");
  char buffer[4096];
  for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) run.output.append(buffer, n);
  const int status = ::pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return run;
}

TEST_F(ConfigTest, ReferenceFileIsValid) {
  // The shipped file: default model and the default clip next to the binary.
  const fs::path reference = fs::path(LIPDRIVE_SOURCE_DIR) / "config" / "lipdrive.toml";
  const CommandRun run = run_lipdrive("check-config " + reference.string());
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_THAT(run.output, HasSubstr(reference.string() + ": ok"));
}

TEST_F(ConfigTest, CheckConfigExitsWithExConfig) {
  write("fps = 500");
  const CommandRun run = run_lipdrive("check-config " + file_.string());
  EXPECT_EQ(run.exit_code, 78) << run.output;
  EXPECT_THAT(run.output, HasSubstr(file_.string() + ": key camera.fps: must be between 1 and 240, got 500"));
  EXPECT_EQ(run_lipdrive("check-config " + (dir_ / "none.toml").string()).exit_code, 78);
}

}  // namespace
}  // namespace lipdrive
