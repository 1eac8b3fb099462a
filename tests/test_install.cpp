// What a studio gets: `cmake --install` puts the product in place and no developer tool, and
// `lipdrive --help` offers no developer command (they are `lipdrive-dev`'s).
#include "build_paths.hpp"
#include "command_run.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

using lipdrive::test::CommandRun;
using lipdrive::test::run_command;

// The developer commands, as `lipdrive-dev` names them.
const std::vector<std::string> kDeveloperCommands = {"fixture", "head", "fit-demo", "generate-head", "ict"};

TEST(Install, TheManifestHoldsTheProductAndNoDeveloperExecutable) {
  const fs::path root = fs::temp_directory_path() / ("lipdrive_test_install_" + std::to_string(::getpid()));
  fs::remove_all(root);
  // DESTDIR as well as the prefix: the configuration's destination is absolute (/etc/... or
  // <prefix>/etc/...), and nothing may land outside the temporary folder.
  const CommandRun install = run_command("DESTDIR=" + root.string() + " " + lipdrive::test::kCmake + " --install " +
                                         lipdrive::test::kBuildDir + " --prefix /opt/lipdrive");
  ASSERT_EQ(install.exit_code, 0) << install.output;

  std::ifstream manifest(fs::path(lipdrive::test::kBuildDir) / "install_manifest.txt");
  ASSERT_TRUE(manifest) << "cmake --install writes install_manifest.txt into the build folder";
  std::vector<fs::path> executables;
  int files = 0;
  bool has_lipdrive = false, has_unit = false, has_udev_rule = false, has_model = false, has_ict = false,
       has_ict_licence = false;
  // The manifest names the files as installed, without DESTDIR.
  for (std::string line; std::getline(manifest, line);) {
    const fs::path file = root / fs::path(line).relative_path();
    ++files;
    EXPECT_TRUE(fs::is_regular_file(file)) << line;
    EXPECT_NE(file.filename(), "lipdrive-dev") << line;
    std::error_code ec;
    const auto permissions = fs::status(file, ec).permissions();
    if (!ec && (permissions & fs::perms::owner_exec) != fs::perms::none) executables.push_back(file);
    has_lipdrive = has_lipdrive || file == root / "opt/lipdrive/bin/lipdrive";
    has_unit = has_unit || file.filename() == "lipdrive.service";
    has_udev_rule = has_udev_rule || file == root / "opt/lipdrive/lib/udev/rules.d/60-lipdrive-gpio.rules";
    has_model = has_model || file.filename() == "default.lpm";
    has_ict = has_ict || file.filename() == "ict_face_light.lpm";
    has_ict_licence = has_ict_licence || file.filename() == "ICT-FaceKit-LICENSE";
  }
  EXPECT_GT(files, 5);
  EXPECT_TRUE(has_lipdrive);
  EXPECT_TRUE(has_unit);
  EXPECT_TRUE(has_udev_rule) << "the GPIO chips to the daemon's gpio group";
  EXPECT_TRUE(has_model);
  EXPECT_TRUE(has_ict) << "the ICT head";
  EXPECT_TRUE(has_ict_licence) << "the ICT head ships with its MIT notice";
  ASSERT_EQ(executables.size(), 1u) << "the one installed executable is lipdrive";
  EXPECT_EQ(executables.front().filename(), "lipdrive");
  fs::remove_all(root);
}

TEST(Install, LipdriveOffersNoDeveloperCommand) {
  const CommandRun help = run_command(std::string(lipdrive::test::kLipdrive) + " --help");
  ASSERT_EQ(help.exit_code, 0) << help.output;
  const CommandRun model_help = run_command(std::string(lipdrive::test::kLipdrive) + " model --help");
  ASSERT_EQ(model_help.exit_code, 0) << model_help.output;
  for (const std::string& command : kDeveloperCommands) {
    EXPECT_THAT(help.output, Not(HasSubstr("  " + command + " "))) << command;
    EXPECT_THAT(model_help.output, Not(HasSubstr("  " + command + " "))) << command;
  }
  EXPECT_NE(run_command(std::string(lipdrive::test::kLipdrive) + " fixture side-view --out /tmp/x").exit_code, 0);

  const CommandRun dev_help = run_command(std::string(lipdrive::test::kLipdriveDev) + " --help");
  ASSERT_EQ(dev_help.exit_code, 0) << dev_help.output;
  for (const char* command : {"fixture", "head", "fit-demo", "ict"})
    EXPECT_THAT(dev_help.output, HasSubstr(std::string("  ") + command + " "));
}

}  // namespace
