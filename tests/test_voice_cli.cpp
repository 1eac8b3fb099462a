// The voice on the command line: `lipdrive voice train` and `voice eval` on GRID clips,
// `lipdrive process --voice`, and bad input: a clip without sound, a missing or damaged
// model, each named with the exit code of other bad input.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "core/voice_training.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"  // test::TempDir

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

/// A small valid 16 kHz voice model, trained on synthetic sound.
VoiceModel synthetic_model() {
  const int rate = 16000;
  std::mt19937 random(1);
  std::normal_distribution<float> noise(0, 1);
  std::vector<VoiceRecording> recordings;
  for (int r = 0; r < 3; ++r) {
    VoiceRecording recording;
    recording.sample_rate = rate;
    recording.samples.resize(static_cast<std::size_t>(2 * rate));
    for (std::size_t i = 0; i < recording.samples.size(); ++i) {
      const double t = static_cast<double>(i) / rate;
      const double open = t > 0.5 && t < 1.5 ? std::sin(std::numbers::pi * (t - 0.5)) : 0.0;
      recording.samples[i] =
          static_cast<float>(0.2 * open * std::sin(2 * std::numbers::pi * 150 * t) + 0.001 * noise(random));
    }
    for (int f = 0; f < 50; ++f) {
      const double t = f / 25.0;
      const float open = t > 0.5 && t < 1.5 ? static_cast<float>(std::sin(std::numbers::pi * (t - 0.5))) : 0.0f;
      recording.targets.push_back({t, {0.05f + 0.3f * open, 1.3f, 0.0f, 0.1f}, true, open > 0.05f});
    }
    recordings.push_back(recording);
  }
  VoiceTrainingSettings settings;
  settings.features.sample_rate = rate;
  settings.features.hop = rate / 100;
  settings.hidden = 0;
  settings.context = {.past = 4, .lookahead = 2, .stride = 2};
  return train_voice_model(recordings, settings);
}

std::string lipdrive(const std::string& args) { return fmt::format("{} {}", test::kLipdrive, args); }

TEST(VoiceCli, BadInputIsNamedWithTheExitCodesOfOtherBadInput) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const test::TempDir dir;
  const fs::path model = dir.path() / "voice.lpv";
  save_voice_model_file(model, synthetic_model());
  // A clip without an audio track: a data error naming the clip.
  test::CommandRun run =
      test::run_command(lipdrive(fmt::format("process {} --voice {}", test::kClip.string(), model.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(run.output.find(test::kClip.string() + ": no audio track"), std::string::npos) << run.output;
  run = test::run_command(
      lipdrive(fmt::format("voice train --out {} {}", (dir.path() / "x.lpv").string(), test::kClip.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(run.output.find("no audio track"), std::string::npos) << run.output;
  // A missing model, and a damaged one.
  run = test::run_command(
      lipdrive(fmt::format("process {} --voice {}", test::kClip.string(), (dir.path() / "absent.lpv").string())));
  EXPECT_EQ(run.exit_code, 66) << run.output;
  EXPECT_NE(run.output.find("absent.lpv: no such model file"), std::string::npos) << run.output;
  std::vector<char> bytes;
  {
    std::ifstream in(model, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  bytes[bytes.size() / 2] ^= 0x10;
  const fs::path damaged = dir.path() / "damaged.lpv";
  std::ofstream(damaged, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  run = test::run_command(
      lipdrive(fmt::format("voice eval --voice {} --test {}", damaged.string(), test::kClip.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(run.output.find(damaged.string() + ": checksum mismatch"), std::string::npos) << run.output;
}

TEST(VoiceCli, TrainEvalAndProcessOnGridClips) {
  const fs::path grid = test::shared_fixtures() / "grid";
  LIPDRIVE_SKIP_WITHOUT_SHARED(grid / "bbaf2n.mpg");
  const test::TempDir dir;
  const fs::path model = dir.path() / "voice.lpv";
  test::CommandRun run = test::run_command(
      lipdrive(fmt::format("voice train --hidden 0 --out {} {}", model.string(), (grid / "lgaf4n.mpg").string())));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("1 recordings, 3.0 s of sound, 75 tracked frames; delay 56 ms (look-ahead 40 ms)"),
            std::string::npos)
      << run.output;
  const fs::path csv = dir.path() / "b.csv";
  run = test::run_command(lipdrive(
      fmt::format("process {} --voice {} --out {}", (grid / "bbaf2n.mpg").string(), model.string(), csv.string())));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  const CsvTable table = read_csv_table(csv);
  ASSERT_EQ(table.rows.size(), 75u);
  for (const char* column : {"open_voice", "width_voice", "protrusion_voice", "seal_voice"}) {
    const std::vector<double> values = numeric_column(table, column);
    EXPECT_TRUE(std::ranges::all_of(values, [](double v) { return std::isfinite(v); })) << column;
  }
  // The rest pose in the silence before the first word, something else while speaking.
  const std::vector<double> open = numeric_column(table, "open_voice");
  EXPECT_EQ(open[5], open[10]);
  EXPECT_NE(*std::ranges::max_element(open), open[5]);
  run = test::run_command(
      lipdrive(fmt::format("voice eval --voice {} --test {}", model.string(), (grid / "bbaf2n.mpg").string())));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  EXPECT_NE(run.output.find("bbaf2n.mpg"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace lipdrive
