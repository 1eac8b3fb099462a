// The voice on the command line: `lipdrive voice train` and `voice eval` on GRID clips,
// `lipdrive process --voice`, and bad input: a clip without sound, a missing or damaged
// model, each named with the exit code of other bad input.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "core/voice_training.hpp"
#include "drivers/audio_file.hpp"
#include "firmware_app/cli/command_error.hpp"
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
#include <sstream>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

/// The synthetic mouth's opening at `t_s`: one word from 0.5 s to 1.5 s.
double synthetic_open(double t_s) { return t_s > 0.5 && t_s < 1.5 ? std::sin(std::numbers::pi * (t_s - 0.5)) : 0.0; }

/// Two seconds of 16 kHz sound whose 150 Hz buzz follows synthetic_open, in a faint noise.
std::vector<float> synthetic_sound(unsigned seed) {
  const int rate = 16000;
  std::mt19937 random(seed);
  std::normal_distribution<float> noise(0, 1);
  std::vector<float> samples(static_cast<std::size_t>(2 * rate));
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const double t = static_cast<double>(i) / rate;
    samples[i] =
        static_cast<float>(0.2 * synthetic_open(t) * std::sin(2 * std::numbers::pi * 150 * t) + 0.001 * noise(random));
  }
  return samples;
}

/// A small valid 16 kHz voice model, trained on synthetic sound.
VoiceModel synthetic_model() {
  const int rate = 16000;
  std::vector<VoiceRecording> recordings;
  for (unsigned r = 0; r < 3; ++r) {
    VoiceRecording recording;
    recording.sample_rate = rate;
    recording.samples = synthetic_sound(r + 1);
    for (int f = 0; f < 50; ++f) {
      const double t = f / 25.0;
      const auto open = static_cast<float>(synthetic_open(t));
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

/// A take as the daemon records it, NAME.csv with its sound NAME.wav: synthetic_sound(seed) and
/// the synthetic mouth at 25 frames a second, the rows' capture times `capture_time_ns`
/// (default: from 1 s on, 40 ms apart).
fs::path write_take(const fs::path& dir, const std::string& name, unsigned seed,
                    std::vector<std::string> capture_time_ns = {}) {
  for (int f = static_cast<int>(capture_time_ns.size()); f < 50; ++f)
    capture_time_ns.push_back(std::to_string(1'000'000'000LL + f * 40'000'000LL));
  const fs::path csv = dir / (name + ".csv");
  std::ofstream out(csv);
  out << "frame,capture_time_ns,tracked,open,width_fit,protrusion_3d,seal\n";
  for (int f = 0; f < 50; ++f)
    out << fmt::format("{},{},1,{:.4f},1.3,0,0.1\n", f, capture_time_ns[static_cast<std::size_t>(f)],
                       0.05 + 0.3 * synthetic_open(f / 25.0));
  WavWriter sound(fs::path(csv).replace_extension(".wav"), 16000);
  sound.write(synthetic_sound(seed));
  sound.close();
  return csv;
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

TEST(VoiceCli, TakesAreScoredOnTheSpeechTheirVoiceActivityHears) {
  const test::TempDir dir;
  const fs::path model = dir.path() / "voice.lpv";
  save_voice_model_file(model, synthetic_model());
  const fs::path a = write_take(dir.path(), "a", 1), b = write_take(dir.path(), "b", 2);
  // Every take's row: its speech frames (the word's 25 of 50), then open's r, σ ratio and
  // final-silence distance, none NaN (the other measures hold still: their r is NaN).
  const auto expect_scored = [](const test::CommandRun& run, const std::string& name) {
    const std::size_t at = run.output.find("\n" + name);
    ASSERT_NE(at, std::string::npos) << run.output;
    std::istringstream row(run.output.substr(at + 1, run.output.find('\n', at + 1) - at - 1));
    std::string recording, r, ratio, silence;
    int frames = 0;
    row >> recording >> frames >> r >> ratio >> silence;
    EXPECT_GT(frames, 15) << run.output;
    for (const std::string& figure : {r, ratio, silence}) EXPECT_NE(figure, "nan") << run.output;
  };
  test::CommandRun run = test::run_command(
      lipdrive(fmt::format("voice eval --voice {} --test {} {}", model.string(), a.string(), b.string())));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  expect_scored(run, "a.csv");
  expect_scored(run, "b.csv");
  const fs::path c = write_take(dir.path(), "c", 3), d = write_take(dir.path(), "d", 4);
  run = test::run_command(lipdrive(fmt::format("voice eval --hidden 0 --past-ms 40 --train {} {} {} {} --folds 2",
                                               a.string(), b.string(), c.string(), d.string())));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* name : {"a.csv", "b.csv", "c.csv", "d.csv"}) expect_scored(run, name);
}

TEST(VoiceCli, ATakeWhoseCaptureTimeIsMissingOrGoesBackIsADataErrorNamingTheLine) {
  const test::TempDir dir;
  const fs::path out = dir.path() / "voice.lpv";
  // Row 3 (line 5, after the header) blank, and row 2 (line 4) before row 1.
  const fs::path blank = write_take(dir.path(), "blank", 1, {"1000000000", "1040000000", "1080000000", ""});
  test::CommandRun run =
      test::run_command(lipdrive(fmt::format("voice train --out {} {}", out.string(), blank.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(run.output.find(blank.string() + ":5: capture_time_ns missing"), std::string::npos) << run.output;
  const fs::path back = write_take(dir.path(), "back", 1, {"1000000000", "1040000000", "1030000000"});
  run = test::run_command(lipdrive(fmt::format("voice train --out {} {}", out.string(), back.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(run.output.find(back.string() + ":4: capture_time_ns earlier than the row before's"), std::string::npos)
      << run.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(VoiceCli, ATakeWhoseRowsRunPastTheEndOfItsSoundIsADataErrorSayingHowFar) {
  const test::TempDir dir;
  const fs::path out = dir.path() / "voice.lpv";
  // The rows span 0 to 1.96 s of their sound: replaced by its first `seconds`.
  const auto cut_sound = [](const fs::path& take, double seconds) {
    std::vector<float> samples = synthetic_sound(1);
    samples.resize(static_cast<std::size_t>(seconds * 16000));
    WavWriter sound(fs::path(take).replace_extension(".wav"), 16000);
    sound.write(samples);
    sound.close();
  };
  // A sound that ends a block or two (20 ms each) before the last row, as the recorder's may.
  const fs::path a = write_take(dir.path(), "a", 1), b = write_take(dir.path(), "b", 2);
  cut_sound(b, 1.92);
  test::CommandRun run = test::run_command(lipdrive(
      fmt::format("voice train --hidden 0 --past-ms 40 --out {} {} {}", out.string(), a.string(), b.string())));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  // Cut short (or another take's): its rows from 1.04 s on (line 28) would be paired with no sound.
  cut_sound(b, 1.0);
  fs::remove(out);
  run = test::run_command(lipdrive(
      fmt::format("voice train --hidden 0 --past-ms 40 --out {} {} {}", out.string(), a.string(), b.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(
      run.output.find(fmt::format("{}:28: this row and the 23 after it lie up to 0.96 s past the end of its sound "
                                  "{} (1.00 s long",
                                  b.string(), fs::path(b).replace_extension(".wav").string())),
      std::string::npos)
      << run.output;
  EXPECT_FALSE(fs::exists(out));

  // Another, longer take's sound: 2.5 s under rows whose last is at 1.96 s.
  cut_sound(b, 2.5);
  run = test::run_command(lipdrive(
      fmt::format("voice train --hidden 0 --past-ms 40 --out {} {} {}", out.string(), a.string(), b.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(run.output.find(fmt::format("{}: 2.50 s long, 0.54 s past the last of the 50 rows of {}; another take's "
                                        "sound",
                                        fs::path(b).replace_extension(".wav").string(), b.string())),
            std::string::npos)
      << run.output;
  EXPECT_FALSE(fs::exists(out));
}

TEST(VoiceCli, ATakeWhoseSoundIsBelow8kHzIsADataErrorNamingItsRate) {
  // 200,000 samples at 10 Hz: 20,000 s, refused before it is resampled (it took 2.3 GB).
  const test::TempDir dir;
  const fs::path take = write_take(dir.path(), "slow", 1);
  const fs::path wav = fs::path(take).replace_extension(".wav");
  WavWriter sound(wav, 10);
  sound.write_silence(200'000);
  sound.close();
  const test::CommandRun run = test::run_command(
      lipdrive(fmt::format("voice train --out {} {}", (dir.path() / "voice.lpv").string(), take.string())));
  EXPECT_EQ(run.exit_code, 65) << run.output;
  EXPECT_NE(run.output.find(wav.string() + ": sound at 10 Hz; at least 8000 Hz"), std::string::npos) << run.output;
}

TEST(VoiceCli, EvalOfATrainedModelNeedsRecordingsToTestOn) {
  const test::TempDir dir;
  const fs::path model = dir.path() / "voice.lpv";
  save_voice_model_file(model, synthetic_model());
  const test::CommandRun run = test::run_command(lipdrive(fmt::format("voice eval --voice {}", model.string())));
  EXPECT_EQ(run.exit_code, kExitUsage) << run.output;
  EXPECT_NE(run.output.find("--test"), std::string::npos) << run.output;
  EXPECT_EQ(run.output.find("nan"), std::string::npos) << run.output;
}

TEST(VoiceCli, EvalRefusesMoreFoldsThanRecordings) {
  // Each fold trained a model, holding none out past the third (--folds 100 on 3 takes: 33 s).
  const test::TempDir dir;
  const fs::path a = write_take(dir.path(), "a", 1), b = write_take(dir.path(), "b", 2),
                 c = write_take(dir.path(), "c", 3);
  const test::CommandRun run = test::run_command(
      lipdrive(fmt::format("voice eval --train {} {} {} --folds 4", a.string(), b.string(), c.string())));
  EXPECT_EQ(run.exit_code, kExitUsage) << run.output;
  EXPECT_NE(run.output.find("--folds: 4 exceeds the 3 recordings of --train"), std::string::npos) << run.output;
  // A trained model is not cross-validated: --folds beside --voice was ignored without a word.
  const fs::path model = dir.path() / "voice.lpv";
  save_voice_model_file(model, synthetic_model());
  const test::CommandRun beside =
      test::run_command(lipdrive(fmt::format("voice eval --voice {} --test {} --folds 2", model.string(), a.string())));
  EXPECT_EQ(beside.exit_code, kExitUsage) << beside.output;
  EXPECT_NE(beside.output.find("--folds: cross-validates --train"), std::string::npos) << beside.output;
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
