// `kill -9` in the middle of a take, then a restart as systemd's Restart=on-failure does it
// (the same command, recording from the configuration): the take keeps every line but at
// most the last, and the restarted daemon reaches its first processed frame (timed).
#include "daemon_process.hpp"
#include "firmware_app/tables/measures_csv.hpp"
#include "fixture_paths.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<fs::path> takes_in(const fs::path& dir) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir, ec)) files.push_back(entry.path());
  std::ranges::sort(files);
  return files;
}

/// The take's lines as written: complete ones, then whatever follows the last newline.
struct TakeLines {
  std::vector<std::string> complete;
  std::string torn;  // empty when the file ends with a newline
};

TakeLines split_lines(const std::string& text) {
  TakeLines lines;
  std::size_t start = 0;
  for (std::size_t end; (end = text.find('\n', start)) != std::string::npos; start = end + 1)
    lines.complete.push_back(text.substr(start, end - start));
  lines.torn = text.substr(start);
  return lines;
}

std::size_t fields(const std::string& line) { return static_cast<std::size_t>(std::ranges::count(line, ',')) + 1; }

TEST(CrashRestart, KillNineMidTakeKeepsTheLinesAndARestartReachesItsFirstFrame) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const fs::path dir = fs::temp_directory_path() / fmt::format("lipdrive_test_crash_{}", ::getpid());
  fs::remove_all(dir);
  const fs::path takes = dir / "takes";
  fs::create_directories(takes);
  const fs::path config = dir / "lipdrive.toml";
  std::ofstream(config) << test::sim_camera_at_60_fps()
                        << fmt::format("[recording]\ndir = \"{}\"\nstart = true\nflush_interval_ms = 100\n",
                                       takes.string());

  {
    test::DaemonProcess daemon(config, dir / "first.txt");
    ASSERT_TRUE(daemon.wait_for_log("recording a take", 120s)) << daemon.log();
    // Rows keep arriving for a while, then the process dies without any chance to finish.
    std::this_thread::sleep_for(2s);
    daemon.signal(SIGKILL);
    daemon.wait(5s);
  }
  const std::vector<fs::path> crashed = takes_in(takes);
  ASSERT_EQ(crashed.size(), 1u);
  const TakeLines lines = split_lines(read_file(crashed[0]));
  ASSERT_FALSE(lines.complete.empty());
  const std::string header = measures_csv_header(false) + ",drive,capture_time_ns";
  EXPECT_EQ(lines.complete[0], header);
  const std::size_t columns = fields(header);
  int rows = 0;
  for (std::size_t i = 1; i < lines.complete.size(); ++i, ++rows)
    ASSERT_EQ(fields(lines.complete[i]), columns) << "line " << i + 1 << ": " << lines.complete[i];
  EXPECT_LT(fields(lines.torn), columns + 1) << "at most the last line is torn";
  EXPECT_GT(rows, 30) << "the take was under way when the daemon was killed";
  RecordProperty("rows_before_kill", rows);
  RecordProperty("torn_bytes", static_cast<int>(lines.torn.size()));

  const auto crashed_size = fs::file_size(crashed[0]);

  // The restart: the time to the first processed frame is the time until the new take's
  // first row is on disk (the recorder writes every 10 ms).
  const auto started = Clock::now();
  test::DaemonProcess restarted(config, dir / "second.txt");
  double first_frame_s = -1;
  while (Clock::now() - started < 120s && restarted.running()) {
    std::vector<fs::path> now = takes_in(takes);
    std::erase(now, crashed[0]);
    if (now.size() == 1 && split_lines(read_file(now[0])).complete.size() >= 2) {
      first_frame_s = std::chrono::duration<double>(Clock::now() - started).count();
      break;
    }
    std::this_thread::sleep_for(5ms);
  }
  ASSERT_GT(first_frame_s, 0) << restarted.log();
  RecordProperty("restart_to_first_frame_ms", static_cast<int>(first_frame_s * 1000));
  std::printf("kill -9 after %d rows (%zu bytes torn); restart to the first processed frame: %.2f s\n", rows,
              lines.torn.size(), first_frame_s);
  EXPECT_EQ(fs::file_size(crashed[0]), crashed_size) << "the crashed take is kept as it was";
  restarted.signal(SIGTERM);
  EXPECT_EQ(restarted.wait(5s), 0) << restarted.log();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lipdrive
