// systemd/lipdrive.service: `systemd-analyze verify` accepts it, and its exposure score
// (`systemd-analyze security --offline=yes`) is reported for the README.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "fixture_paths.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;

using lipdrive::test::CommandRun;

CommandRun run(const std::string& command) { return lipdrive::test::run_command(command); }

class SystemdUnitTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // scripts/install-deps.sh installs systemd: CI (LIPDRIVE_REQUIRE_FIXTURES=1) must have it.
    if (run("systemd-analyze --version").exit_code != 0) {
      if (lipdrive::test::fixtures_required()) FAIL() << "no systemd-analyze (package systemd)";
      GTEST_SKIP() << "no systemd-analyze (package systemd)";
    }
    dir_ = fs::temp_directory_path() / ("lipdrive_test_unit_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// The unit with ExecStart's binary replaced by `binary` (verify checks that it exists).
  fs::path unit_running(const std::string& binary) const {
    std::ifstream in(fs::path(lipdrive::test::kSourceDir) / "systemd" / "lipdrive.service");
    std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
    const std::string installed = "ExecStart=/usr/bin/lipdrive ";
    const auto at = text.find(installed);
    EXPECT_NE(at, std::string::npos);
    text.replace(at, installed.size(), "ExecStart=" + binary + " ");
    const fs::path unit = dir_ / "lipdrive.service";
    std::ofstream(unit) << text;
    return unit;
  }

  fs::path dir_;
};

TEST_F(SystemdUnitTest, VerifyAcceptsTheUnit) {
  // --man=no: Documentation=man:lipdrive(1) is installed by the package (test_package), not here.
  const CommandRun verify = run("systemd-analyze verify --man=no " + unit_running(lipdrive::test::kLipdrive).string());
  EXPECT_EQ(verify.exit_code, 0) << verify.output;
  EXPECT_THAT(verify.output, ::testing::Not(::testing::HasSubstr("lipdrive.service"))) << "no warnings";
}

TEST_F(SystemdUnitTest, VerifyRejectsAMissingBinary) {
  // Shows that the check above can fail.
  const CommandRun verify = run("systemd-analyze verify " + unit_running((dir_ / "no-such-binary").string()).string());
  EXPECT_NE(verify.exit_code, 0) << verify.output;
}

TEST_F(SystemdUnitTest, ExposureScore) {
  const CommandRun security =
      run("systemd-analyze security --offline=yes " + unit_running(lipdrive::test::kLipdrive).string());
  std::smatch match;
  ASSERT_TRUE(
      std::regex_search(security.output, match, std::regex(R"(Overall exposure level for \S+: ([0-9.]+) (\w+))")))
      << security.output;
  const double score = std::stod(match[1]);
  std::printf("systemd-analyze security --offline=yes: exposure %.1f %s\n", score, match[2].str().c_str());
  RecordProperty("exposure", match[1].str());
  // 0 = fully confined, 10 = unprotected.
  EXPECT_LE(score, 1.5) << security.output;
}

TEST_F(SystemdUnitTest, EveryRemainingExposureIsExplainedInTheUnit) {
  const CommandRun security =
      run("systemd-analyze security --offline=yes " + unit_running(lipdrive::test::kLipdrive).string());
  std::ifstream in(fs::path(lipdrive::test::kSourceDir) / "systemd" / "lipdrive.service");
  std::string comments;
  for (std::string line; std::getline(in, line);)
    if (line.rfind('#', 0) == 0) comments += line + '\n';
  // An open item reads "✗ Setting=... description score": its setting must be named in a comment.
  const std::regex open_item("\xE2\x9C\x97 ([A-Za-z]+)=");
  int open = 0;
  for (auto it = std::sregex_iterator(security.output.begin(), security.output.end(), open_item);
       it != std::sregex_iterator(); ++it, ++open) {
    const std::string setting = (*it)[1].str() + "=";
    EXPECT_NE(comments.find(setting), std::string::npos) << setting << " is open and not explained in the unit";
  }
  EXPECT_GT(open, 0) << security.output;
}

}  // namespace
