// The Debian package (packaging/, docs/packaging.md): `cpack -G DEB` builds
// lipdrive_<version>_<arch>.deb from this build; its contents, control data and lintian's
// verdict are checked, and it is installed into a scratch root with dpkg, its maintainer
// scripts included, where the unit must find everything it names and the installed binary
// must run the installed configuration.
//
// The package, its contents list and lintian's output stay in <build>/test_artifacts/package.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "daemon_process.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/paths.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

namespace {

namespace fs = std::filesystem;
using lipdrive::test::CommandRun;
using lipdrive::test::run_command;
using ::testing::HasSubstr;
using ::testing::Not;

const fs::path kArtifacts = fs::path(lipdrive::test::kBuildDir) / "test_artifacts" / "package";

// Every file the package installs, with its mode.
const std::map<std::string, unsigned> kExpectedFiles = {
    {"/etc/lipdrive/lipdrive.toml", 0644},
    {"/usr/bin/lipdrive", 0755},
    {"/usr/lib/systemd/system/lipdrive.service", 0644},
    {"/usr/lib/sysusers.d/lipdrive.conf", 0644},
    {"/usr/lib/udev/rules.d/60-lipdrive-gpio.rules", 0644},
    {"/usr/share/doc/lipdrive/changelog.gz", 0644},
    {"/usr/share/doc/lipdrive/copyright", 0644},
    {"/usr/share/lipdrive/models/ICT-FaceKit-LICENSE", 0644},
    {"/usr/share/lipdrive/models/default.lpm", 0644},
    {"/usr/share/lipdrive/models/default17.lpm", 0644},
    {"/usr/share/lipdrive/models/ict_face_light.lpm", 0644},
    {"/usr/share/lipdrive/talking_face.avi", 0644},
    {"/usr/share/man/man1/lipdrive.1.gz", 0644},
};

// Tags lintian may report (all of them informational), each with the reason it stays;
// any other tag fails the test.
const std::map<std::string, std::string> kExplainedTags = {
    {"arch-dep-package-has-big-usr-share",
     "the replay clip (14 MB) and the models: one package is simpler to install on a rig than a "
     "separate lipdrive-data"},
    {"binary-has-unneeded-section", "CPack's strip keeps the .comment section (compiler version strings)"},
    {"hardening-no-fortify-functions",
     "-D_FORTIFY_SOURCE is not among the build's compile flags; adding it rebuilds every object"},
    {"package-supports-alternative-init-but-no-init.d-script",
     "the daemon needs systemd (Type=notify, the watchdog); there is no init.d script to offer"},
};

std::string shell_quote(const fs::path& path) { return "'" + path.string() + "'"; }

std::string read_file(const fs::path& path) {
  std::ifstream in(path);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// The .deb, built once for all tests.
class Package : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    fs::remove_all(kArtifacts);
    fs::create_directories(kArtifacts);
    const CommandRun arch = run_command("dpkg --print-architecture");
    ASSERT_EQ(arch.exit_code, 0) << arch.output;
    architecture_ = arch.output.substr(0, arch.output.find('\n'));
    // -B: the staging tree and the package go to the artefacts, not into the build tree.
    build_ = new CommandRun(run_command(fmt::format("cd {} && {} -G DEB --config CPackConfig.cmake -B {}",
                                                    shell_quote(lipdrive::test::kBuildDir), lipdrive::test::kCpack,
                                                    shell_quote(kArtifacts))));
    deb_ = kArtifacts / fmt::format("lipdrive_{}_{}.deb", lipdrive::test::kVersion, architecture_);
  }
  static void TearDownTestSuite() {
    delete build_;
    build_ = nullptr;
    fs::remove_all(kArtifacts / "_CPack_Packages");  // the staging tree; the .deb stays
  }
  void SetUp() override {
    ASSERT_EQ(build_->exit_code, 0) << build_->output;
    ASSERT_TRUE(fs::is_regular_file(deb_)) << deb_ << " is the name Debian gives it\n" << build_->output;
  }

  static std::string field(const std::string& name) {
    const CommandRun run = run_command(fmt::format("dpkg-deb --field {} {}", shell_quote(deb_), name));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    std::string value = run.output;
    while (!value.empty() && value.back() == '\n') value.pop_back();
    return value;
  }

  static inline CommandRun* build_ = nullptr;
  static inline std::string architecture_;
  static inline fs::path deb_;
};

TEST_F(Package, ContentsAreTheProductWithDebiansModesAndOwners) {
  const CommandRun contents = run_command("dpkg-deb --contents " + shell_quote(deb_));
  ASSERT_EQ(contents.exit_code, 0) << contents.output;
  std::ofstream(kArtifacts / "contents.txt") << contents.output;
  std::cout << contents.output;
  // drwxr-xr-x root/root         0 2026-12-02 04:00 ./usr/bin/
  // -rwxr-xr-x root/root   5812744 2026-12-02 04:00 ./usr/bin/lipdrive
  const std::regex line(R"(^([dl-])([rwx-]{9}) (\S+)/(\S+) +\d+ \S+ \S+ \.(\S+?)/?( -> .*)?$)");
  std::map<std::string, unsigned> files;
  std::istringstream lines(contents.output);
  for (std::string text; std::getline(lines, text);) {
    std::smatch m;
    ASSERT_TRUE(std::regex_match(text, m, line)) << text;
    EXPECT_EQ(m[3], "root") << text;
    EXPECT_EQ(m[4], "root") << text;
    if (m[1] == "d") {
      EXPECT_EQ(m[2], "rwxr-xr-x") << text;
      continue;
    }
    ASSERT_EQ(m[1], "-") << "no links: " << text;
    unsigned mode = 0;
    for (const char c : m[2].str()) mode = mode << 1 | (c != '-');
    files[m[5]] = mode;
  }
  EXPECT_EQ(files, kExpectedFiles);
}

TEST_F(Package, ControlDataDeclaresTheLinkedLibrariesAndTheConffile) {
  EXPECT_EQ(field("Package"), "lipdrive");
  EXPECT_EQ(field("Version"), lipdrive::test::kVersion);
  EXPECT_EQ(field("Architecture"), architecture_);
  const std::string depends = field("Depends");
  RecordProperty("depends", depends);
  // Every shared library the binary links comes from a package named in Depends.
  const CommandRun needed =
      run_command(fmt::format("objdump -p {} | awk '/NEEDED/ {{print $2}}'", lipdrive::test::kLipdrive));
  ASSERT_EQ(needed.exit_code, 0) << needed.output;
  std::istringstream libraries(needed.output);
  int count = 0;
  for (std::string soname; std::getline(libraries, soname);) {
    ++count;
    // The package that owns the library the dynamic linker resolves for the soname.
    const CommandRun owner = run_command(fmt::format(
        "dpkg -S \"$(ldconfig -p | awk '$1 == \"{}\" && /x86-64|{}/ {{print $NF; exit}}' | xargs -r realpath)\" "
        "| cut -d: -f1",
        soname, architecture_));
    ASSERT_EQ(owner.exit_code, 0) << soname << ": " << owner.output;
    const std::string package = owner.output.substr(0, owner.output.find('\n'));
    EXPECT_THAT(depends, HasSubstr(package)) << soname << " comes from " << package;
  }
  EXPECT_GT(count, 10) << needed.output;
  EXPECT_THAT(depends, HasSubstr("libdlib-data")) << "the default landmark predictor";

  const CommandRun conffiles = run_command(fmt::format("dpkg-deb --info {} conffiles", shell_quote(deb_)));
  ASSERT_EQ(conffiles.exit_code, 0) << conffiles.output;
  EXPECT_EQ(conffiles.output, "/etc/lipdrive/lipdrive.toml\n");
  for (const char* script : {"postinst", "prerm", "postrm"}) {
    const CommandRun text = run_command(fmt::format("dpkg-deb --info {} {}", shell_quote(deb_), script));
    EXPECT_EQ(text.exit_code, 0) << script << " is in the package";
  }
}

TEST_F(Package, LintianReportsOnlyExplainedTags) {
  // Every occurrence of every tag, the informational ones included.
  const CommandRun lintian =
      run_command("lintian --tag-display-limit 0 --display-info --allow-root " + shell_quote(deb_));
  std::ofstream(kArtifacts / "lintian.txt") << lintian.output;
  std::cout << "lintian:\n" << lintian.output << "(end)\n";
  RecordProperty("lintian", lintian.output);
  // "E: lipdrive: tag-name [detail]" / "W: ..." / "I: ..."
  const std::regex tag(R"(^([EWIP]): lipdrive(?: \(\w+\))?: (\S+).*$)");
  std::istringstream lines(lintian.output);
  for (std::string text; std::getline(lines, text);) {
    std::smatch m;
    if (!std::regex_match(text, m, tag)) continue;
    EXPECT_TRUE(kExplainedTags.contains(m[2])) << text;
  }
  EXPECT_THAT(lintian.exit_code, ::testing::AnyOf(0, 2)) << lintian.output;  // 2: tags found
}

/// dpkg acting on a scratch root: files, the status database and the maintainer scripts run
/// outside a chroot with DPKG_ROOT set (they change only that root).
CommandRun dpkg_in(const fs::path& root, const std::string& arguments) {
  return run_command(
      fmt::format("dpkg --root={} --force-script-chrootless --force-depends {}", shell_quote(root), arguments));
}

/// `Key=` values of a unit file.
std::string unit_value(const std::string& unit, const std::string& key) {
  std::smatch m;
  EXPECT_TRUE(std::regex_search(unit, m, std::regex("\n" + key + "=([^\n]*)"))) << key;
  return m[1];
}

TEST_F(Package, InstalledIntoAScratchRootEverythingIsWhereTheUnitExpectsIt) {
  const fs::path root = fs::temp_directory_path() / fmt::format("lipdrive_test_package_{}", ::getpid());
  fs::remove_all(root);
  for (const char* dir : {"var/lib/dpkg/info", "var/lib/dpkg/updates", "var/lib/dpkg/triggers", "etc"})
    fs::create_directories(root / dir);
  std::ofstream(root / "var/lib/dpkg/status").flush();
  // libdlib-data's predictor (a Depends): postinst converts it into the compact file.
  const fs::path dlib_predictor = root / fs::path(lipdrive::kDebianPredictorPath).relative_path();
  fs::create_directories(dlib_predictor.parent_path());
  fs::copy_file(lipdrive::kDebianPredictorPath, dlib_predictor);
  const fs::path compact_predictor = root / "usr/share/lipdrive/models/face_landmarks.lpp";

  const CommandRun install = dpkg_in(root, "--install " + shell_quote(deb_));
  ASSERT_EQ(install.exit_code, 0) << install.output;
  EXPECT_THAT(read_file(root / "var/lib/dpkg/status"), HasSubstr("Package: lipdrive\nStatus: install ok installed"));
  for (const auto& [file, mode] : kExpectedFiles) {
    struct stat s {};
    ASSERT_EQ(::stat((root.string() + file).c_str(), &s), 0) << file;
    EXPECT_EQ(s.st_mode & 07777, mode) << file;
  }

  // What the unit names: the binary, its configuration, the user, the state directory.
  const std::string unit = read_file(root / "usr/lib/systemd/system/lipdrive.service");
  const std::string exec_start = unit_value(unit, "ExecStart");
  std::smatch m;
  ASSERT_TRUE(std::regex_match(exec_start, m, std::regex(R"((/\S+) run --config (/\S+))"))) << exec_start;
  const fs::path binary = root.string() + m[1].str(), config = root.string() + m[2].str();
  EXPECT_EQ(::access(binary.c_str(), X_OK), 0) << binary;
  EXPECT_TRUE(fs::is_regular_file(config)) << config;
  // Restarted on everything but what only an edit mends (64, 78): a name server not up yet at
  // boot (75), a crash; with no start limit, which would leave the figure dead after a few quick
  // restarts in a row.
  const std::string kept_down = " " + unit_value(unit, "RestartPreventExitStatus") + " ";
  for (const int code : {lipdrive::kExitUsage, lipdrive::kExitConfig}) EXPECT_THAT(kept_down, HasSubstr(fmt::format(" {} ", code)));
  EXPECT_THAT(kept_down, Not(HasSubstr(fmt::format(" {} ", lipdrive::kExitTryAgain))));
  EXPECT_EQ(unit_value(unit, "Restart"), "on-failure");
  EXPECT_EQ(unit_value(unit, "StartLimitIntervalSec"), "0");
  // postinst: the user the unit runs as (systemd-sysusers), the unit enabled.
  const std::string user = unit_value(unit, "User");
  EXPECT_TRUE(std::regex_search(read_file(root / "etc/passwd"), std::regex("(^|\n)" + user + ":x:")))
      << read_file(root / "etc/passwd");
  EXPECT_THAT(read_file(root / "etc/passwd"), HasSubstr(":/var/lib/" + unit_value(unit, "StateDirectory") + ":"));
  // The udev rule gives the GPIO chips to a group the unit gives the daemon and postinst created.
  const std::string rule = read_file(root / "usr/lib/udev/rules.d/60-lipdrive-gpio.rules");
  ASSERT_TRUE(std::regex_search(
      rule, m, std::regex(R"re((^|\n)SUBSYSTEM=="gpio", KERNEL=="gpiochip\*", GROUP="([\w-]+)", MODE="0660"\n)re")))
      << rule;
  const std::string gpio_group = m[2];
  EXPECT_THAT(" " + unit_value(unit, "SupplementaryGroups") + " ", HasSubstr(" " + gpio_group + " "));
  EXPECT_TRUE(std::regex_search(read_file(root / "etc/group"), std::regex("(^|\n)" + gpio_group + ":x:")))
      << read_file(root / "etc/group");
  // The user is a member of every group the unit gives the daemon, so a command run by hand as
  // that user reaches the same devices.
  std::istringstream groups(unit_value(unit, "SupplementaryGroups"));
  for (std::string group; groups >> group;)
    EXPECT_TRUE(std::regex_search(read_file(root / "etc/group"),
                                  std::regex("(^|\n)" + group + ":x:\\d+:([^\n]*,)?" + user + "(,|\n)")))
        << group << " lacks " << user << ":\n"
        << read_file(root / "etc/group");
  const fs::path wants = root / "etc/systemd/system/multi-user.target.wants/lipdrive.service";
  ASSERT_TRUE(fs::is_symlink(wants)) << "the unit is enabled on install";
  EXPECT_TRUE(fs::is_regular_file(root.string() + fs::read_symlink(wants).string())) << fs::read_symlink(wants);

  // The installed binary finds its models and clip beside it and runs the installed file: as
  // it is (check-config), and with free Modbus and monitor ports (the only change) for 30 frames.
  const CommandRun check = run_command(fmt::format("{} check-config {}", shell_quote(binary), shell_quote(config)));
  EXPECT_EQ(check.exit_code, 0) << check.output;
  std::string text = read_file(config);
  const std::string port = "port = 1502";
  ASSERT_NE(text.find(port), std::string::npos) << "the reference Modbus server";
  text.replace(text.find(port), port.size(), fmt::format("port = {}", lipdrive::test::free_port()));
  const std::string monitor_port = "port = 8480";
  ASSERT_NE(text.find(monitor_port), std::string::npos) << "the reference monitor page";
  const int free_monitor_port = lipdrive::test::free_port();
  text.replace(text.find(monitor_port), monitor_port.size(), fmt::format("port = {}", free_monitor_port));
  const fs::path run_config = root / "run.toml";
  std::ofstream(run_config) << text;
  const CommandRun run =
      run_command(fmt::format("{} run --config {} --frames 30 --stats", shell_quote(binary), shell_quote(run_config)));
  EXPECT_EQ(run.exit_code, 0) << run.output;
  ASSERT_TRUE(std::regex_search(run.output, m, std::regex(R"(processed (\d+))"))) << run.output;
  EXPECT_GE(std::stoi(m[1]), 30) << run.output;
  EXPECT_THAT(run.output, HasSubstr(root.string() + "/usr/share/lipdrive/models/ict_face_light.lpm")) << run.output;
  EXPECT_THAT(run.output, HasSubstr("predictor " + compact_predictor.string())) << run.output;
  EXPECT_THAT(run.output, HasSubstr(root.string() + "/usr/share/lipdrive/talking_face.avi")) << run.output;
  EXPECT_THAT(run.output, HasSubstr(fmt::format("monitor: http://127.0.0.1:{}/", free_monitor_port))) << run.output;

  // An upgrade keeps an administrator's disable and a changed configuration.
  const CommandRun disable =
      run_command(fmt::format("systemctl --root={} disable lipdrive.service", shell_quote(root)));
  ASSERT_EQ(disable.exit_code, 0) << disable.output;
  ASSERT_FALSE(fs::exists(wants));
  std::ofstream(config, std::ios::app) << "# changed on this rig\n";
  const CommandRun upgrade = dpkg_in(root, "--install " + shell_quote(deb_));
  ASSERT_EQ(upgrade.exit_code, 0) << upgrade.output;
  EXPECT_FALSE(fs::exists(wants)) << "disabled stays disabled";
  EXPECT_THAT(read_file(config), HasSubstr("# changed on this rig"));

  // Removal keeps the configuration; purge takes it.
  EXPECT_TRUE(fs::is_regular_file(compact_predictor)) << "postinst converts libdlib-data's predictor";
  const CommandRun remove = dpkg_in(root, "--remove lipdrive");
  ASSERT_EQ(remove.exit_code, 0) << remove.output;
  EXPECT_FALSE(fs::exists(binary));
  EXPECT_FALSE(fs::exists(compact_predictor)) << "what postinst made goes with the package";
  EXPECT_TRUE(fs::exists(config)) << "a conffile stays until purge";
  const CommandRun purge = dpkg_in(root, "--purge lipdrive");
  ASSERT_EQ(purge.exit_code, 0) << purge.output;
  EXPECT_FALSE(fs::exists(config));
  fs::remove_all(root);
}

// The manual page the package installs names every command `lipdrive --help` lists, in its
// synopsis and among its commands ("check-config" as groff writes it, "check\-config").
TEST(ManualPage, NamesEveryCommandTheProgramHas) {
  const std::string page = read_file(fs::path(lipdrive::test::kSourceDir) / "packaging" / "lipdrive.1");
  const std::string help = lipdrive::test::run_command(std::string(lipdrive::test::kLipdrive) + " --help").output;
  const std::string listed = help.substr(help.find("Subcommands:"));
  std::smatch m;
  int commands = 0;
  for (auto at = listed.cbegin(); std::regex_search(at, listed.cend(), m, std::regex(R"(\n  ([a-z][a-z-]+) )"));
       at = m[0].second) {
    std::string name = std::regex_replace(m[1].str(), std::regex("-"), "\\-");
    const std::string synopsis = ".B lipdrive " + name;
    EXPECT_TRUE(page.find(synopsis + "\n") != std::string::npos || page.find(synopsis + " ") != std::string::npos)
        << name << " is not in the synopsis";
    EXPECT_THAT(page, HasSubstr(".TP\n.B " + name + "\n")) << name << " is not among the commands";
    ++commands;
  }
  EXPECT_GE(commands, 9) << help;
}

}  // namespace
