// The voice room ([voice], docs/voice.md): the microphone's blocks through the voice model on a
// thread of its own, the newest prediction published latest-wins without a heap allocation per
// block; and a voice that cannot be heard (a damaged model, one for another sample rate, a
// clip without sound, an unknown sound card) leaves `lipdrive run` driving from the video.
#include "allocation_counter.hpp"
#include "build_paths.hpp"
#include "command_run.hpp"
#include "daemon_process.hpp"
#include "drivers/audio_file.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/take_recorder.hpp"
#include "firmware_app/daemon/take_sound.hpp"
#include "firmware_app/daemon/voice_room.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <fstream>
#include <numbers>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr std::int64_t kStartNs = 7'000'000'000;
constexpr int kRate = 16000, kBlock = 160;

/// A linear model of 2 cepstra that predicts open = 0.3 while the voice is heard and rests at
/// 0.05: what the room does with a prediction, not what a trained model predicts.
VoiceModel constant_model(int sample_rate = kRate) {
  VoiceModel m;
  m.features.sample_rate = sample_rate;
  m.features.hop = sample_rate / 100;
  m.features.window = sample_rate == kRate ? 512 : 256;
  m.features.max_hz = 0.45f * static_cast<float>(sample_rate);
  m.features.cepstra = 2;
  m.features.mel_bands = 4;
  m.context = {.past = 4, .lookahead = 2, .stride = 2};
  m.feature_mean = Eigen::VectorXf::Zero(2);
  m.feature_scale = Eigen::VectorXf::Ones(2);
  m.weights = Eigen::MatrixXf::Zero(kNumVoiceTargets, m.inputs());
  m.bias = Eigen::VectorXf::Zero(kNumVoiceTargets);
  m.bias[0] = 0.3f;
  m.gain.fill(1);
  m.rest = {0.05f, 1.3f, 0.0f, 0.9f};
  m.smoothing_s = 0;
  m.gate_s = 0;
  return m;
}

/// 10 ms blocks of a tone, loud from `loud_from` on (quiet before), stamped kStartNs + n·10 ms
/// and delivered at once; then nothing. Counts the reading thread's allocations from block
/// `count_from` to the last.
class ScriptedSound final : public AudioSource {
 public:
  ScriptedSound(int blocks, int loud_from, int count_from)
      : blocks_(blocks), loud_from_(loud_from), count_from_(count_from) {}
  AudioStatus read(AudioBlock& block, std::chrono::milliseconds timeout) override {
    if (next_ == count_from_) test::count_allocations_on_this_thread(true);
    if (next_ == blocks_) {
      test::count_allocations_on_this_thread(false);
      ++next_;
    }
    if (next_ > blocks_) {
      std::this_thread::sleep_for(std::min<std::chrono::milliseconds>(timeout, 5ms));
      return AudioStatus::kTimeout;
    }
    const float amplitude = next_ >= loud_from_ ? 0.3f : 0.0003f;
    for (int i = 0; i < kBlock; ++i) {
      const double t = static_cast<double>(next_ * kBlock + i) / kRate;
      block.samples[static_cast<std::size_t>(i)] =
          amplitude * static_cast<float>(std::sin(2 * std::numbers::pi * 220 * t));
    }
    block.frames = kBlock;
    block.sample_rate = kRate;
    block.capture_time_ns = kStartNs + next_ * 10'000'000LL;
    block.position = static_cast<std::uint64_t>(next_ * kBlock);
    ++next_;
    return AudioStatus::kBlock;
  }
  int sample_rate() const override { return kRate; }
  std::string describe() const override { return "scripted"; }

 private:
  int blocks_, loud_from_, count_from_;
  int next_ = 0;
};

TEST(VoiceRoom, PublishesTheNewestPredictionOnTheSoundsClockWithoutAllocatingPerBlock) {
  constexpr int kBlocks = 400, kLoudFrom = 250, kCountFrom = 50;
  const VoiceModel model = constant_model();
  const long before = test::allocation_count();
  VoiceRoom room(std::make_unique<ScriptedSound>(kBlocks, kLoudFrom, kCountFrom), model);
  ASSERT_TRUE(test::eventually([&] { return room.blocks() == kBlocks; }, 10s));
  VoiceState state;
  ASSERT_GT(room.latest(state), 0u);
  EXPECT_EQ(test::allocation_count() - before, 0) << "blocks " << kCountFrom << ".." << kBlocks - 1;
  EXPECT_TRUE(state.active);
  EXPECT_FLOAT_EQ(state.measures[0], 0.3f);
  // The newest block ends at 400 · 10 ms; the prediction is for the window centre the
  // look-ahead (2 frames) before the newest frame's: 10 ms + 20 ms + 16 ms before the end.
  EXPECT_EQ(state.heard_ns, kStartNs + kBlocks * 10'000'000LL);
  EXPECT_EQ(state.time_ns, state.heard_ns - std::llround(model.delay_s() * 1e9));
  EXPECT_EQ(room.problem(), "");
}

TEST(VoiceRoom, AQuietVoiceRestsAndIsNewestFirst) {
  VoiceRoom room(std::make_unique<ScriptedSound>(200, 1000, 1000), constant_model());
  ASSERT_TRUE(test::eventually([&] { return room.blocks() == 200; }, 10s));
  VoiceState state;
  room.latest(state);
  EXPECT_FALSE(state.active);
  EXPECT_FLOAT_EQ(state.measures[0], 0.05f) << "the rest pose";
  EXPECT_FLOAT_EQ(state.measures[3], 0.9f);
}

// ---- the takes' sound ----------------------------------------------------------------------

/// Sample n of a signal on one timeline: captured at kStartNs + n / kRate s.
float timeline_sample(std::int64_t n) { return static_cast<float>(((n * 37) % 200 + 200) % 200 - 100) / 200.0f; }
std::int64_t timeline_ns(std::int64_t n) { return kStartNs + n * 1'000'000'000 / kRate; }

AudioBlock timeline_block(std::int64_t first, std::int64_t stamp_offset = 0) {
  AudioBlock block;
  for (int i = 0; i < kBlock; ++i) block.samples[static_cast<std::size_t>(i)] = timeline_sample(first + i);
  block.frames = kBlock;
  block.sample_rate = kRate;
  block.capture_time_ns = timeline_ns(first + stamp_offset);
  return block;
}

std::int64_t fake_now_ns = 0;

TEST(TakeSound, TheFilesFirstSampleIsTheFirstRowsAndGapsAreSilence) {
  test::TempDir dir;
  const fs::path wav = dir.path() / "take.wav";
  fake_now_ns = timeline_ns(6 * kBlock);  // the clock just after the last block
  TakeSound sound(kRate, [] { return fake_now_ns; });
  sound.open(wav);
  sound.push(timeline_block(-kBlock));  // before the first row: cut
  sound.push(timeline_block(0));        // holds the first row's sample 100
  sound.push(timeline_block(kBlock));
  sound.drain();  // waits for the first row
  sound.start_at(timeline_ns(100));
  sound.push(timeline_block(kBlock));  // again: nothing new
  sound.drain();
  // Block 3 is lost; block 5's stamp is 1 sample late (clock jitter): it continues block 4.
  const long before = test::allocation_count();
  test::count_allocations_on_this_thread(true);
  sound.push(timeline_block(2 * kBlock));
  sound.push(timeline_block(4 * kBlock));
  sound.push(timeline_block(5 * kBlock, 1));
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(test::allocation_count() - before, 0) << "push() allocates nothing";
  sound.close();

  const DecodedAudio back = decode_audio(wav, kRate);
  ASSERT_EQ(back.samples.size(), static_cast<std::size_t>(6 * kBlock - 100));
  for (std::size_t k = 0; k < back.samples.size(); ++k) {
    const std::int64_t n = 100 + static_cast<std::int64_t>(k);
    const float expected = n >= 3 * kBlock && n < 4 * kBlock ? 0.0f : timeline_sample(n);
    ASSERT_NEAR(back.samples[k], expected, 1e-4) << "file sample " << k << " (timeline " << n << ")";
  }
}

TEST(TakeSound, ALongWaitForTheFirstRowLosesNoneOfTheTakesSound) {
  // The camera is away when the take starts: 5 s of sound (more than the ring holds) before the
  // first row. The file still starts with the first row's sample.
  test::TempDir dir;
  const fs::path wav = dir.path() / "take.wav";
  TakeSound sound(kRate, [] { return fake_now_ns; });
  sound.open(wav);
  constexpr int kWait = 500, kAfter = 20;
  for (int b = 0; b < kWait + kAfter; ++b) {
    sound.push(timeline_block(b * kBlock));
    fake_now_ns = timeline_ns((b + 1) * kBlock);
    if (b == kWait) sound.start_at(timeline_ns(kWait * kBlock + 100));
    if (b % 10 == 0) sound.drain();  // the recorder's pace
  }
  sound.close();
  const DecodedAudio back = decode_audio(wav, kRate);
  ASSERT_EQ(back.samples.size(), static_cast<std::size_t>(kAfter * kBlock - 100));
  for (std::size_t k = 0; k < back.samples.size(); ++k)
    ASSERT_NEAR(back.samples[k], timeline_sample(kWait * kBlock + 100 + static_cast<std::int64_t>(k)), 1e-4)
        << "file sample " << k;
}

TEST(TakeSound, WithoutATakeTheBlocksAreDropped) {
  test::TempDir dir;
  TakeSound sound(kRate);
  for (int b = 0; b < 1000; ++b) {  // far more than the ring holds: drained, nothing kept
    sound.push(timeline_block(b * kBlock));
    sound.drain();
  }
  sound.open(dir.path() / "take.wav");
  sound.start_at(timeline_ns(1000 * kBlock));
  sound.push(timeline_block(1000 * kBlock));
  sound.close();
  EXPECT_EQ(decode_audio(dir.path() / "take.wav", kRate).samples.size(), static_cast<std::size_t>(kBlock));
}

// The clock a TakeSound reads in the tests below.

// A block stamped later than the clock reads (the audio clock jumped ahead) is left out rather
// than reached with hours of silence; the blocks after it go on where the sound was.
TEST(TakeSound, ABlockStampedAheadOfTheClockIsLeftOutNotFilledUpTo) {
  test::TempDir dir;
  const fs::path wav = dir.path() / "take.wav";
  fake_now_ns = timeline_ns(10 * kBlock);
  TakeSound sound(kRate, [] { return fake_now_ns; });
  sound.open(wav);
  sound.start_at(timeline_ns(0));
  sound.push(timeline_block(0));
  AudioBlock jumped = timeline_block(kBlock);
  jumped.capture_time_ns += 2LL * 3600 * 1'000'000'000;  // two hours ahead
  sound.push(jumped);
  sound.push(timeline_block(kBlock));
  sound.close();
  const DecodedAudio back = decode_audio(wav, kRate);
  ASSERT_EQ(back.samples.size(), static_cast<std::size_t>(2 * kBlock));
  for (std::size_t k = 0; k < back.samples.size(); ++k)
    ASSERT_NEAR(back.samples[k], timeline_sample(static_cast<std::int64_t>(k)), 1e-4) << "sample " << k;
}

// The take's sound ends with its last row: the recorder writes it half a second behind the
// clock, and when the take stops what was heard after the last row is cut. Sound written before
// (a stretch of the take without rows) stays.
TEST(TakeSound, EndsWithTheTakesLastRow) {
  test::TempDir dir;
  fake_now_ns = timeline_ns(10 * kBlock);  // 100 ms after the first block: every block is recent
  TakeSound sound(kRate, [] { return fake_now_ns; });
  sound.open(dir.path() / "cut.wav");
  sound.start_at(timeline_ns(0));
  for (int b = 0; b < 10; ++b) sound.push(timeline_block(b * kBlock));
  sound.drain();  // all within the last half second: held
  sound.close(timeline_ns(5 * kBlock + 40));
  const DecodedAudio cut = decode_audio(dir.path() / "cut.wav", kRate);
  ASSERT_EQ(cut.samples.size(), static_cast<std::size_t>(5 * kBlock + 40));
  for (std::size_t k = 0; k < cut.samples.size(); ++k)
    ASSERT_NEAR(cut.samples[k], timeline_sample(static_cast<std::int64_t>(k)), 1e-4) << "sample " << k;

  fake_now_ns = timeline_ns(200 * kBlock);  // 2 s on: the same blocks are old enough to write
  sound.open(dir.path() / "kept.wav");
  sound.start_at(timeline_ns(0));
  for (int b = 0; b < 10; ++b) sound.push(timeline_block(b * kBlock));
  sound.drain();
  sound.close(timeline_ns(3 * kBlock));
  EXPECT_EQ(decode_audio(dir.path() / "kept.wav", kRate).samples.size(), static_cast<std::size_t>(10 * kBlock));
}

// Whether this process holds `file` open.
bool open_here(const fs::path& file) {
  const fs::path target = fs::canonical(file);
  for (const auto& fd : fs::directory_iterator("/proc/self/fd")) {
    std::error_code ec;
    if (fs::read_symlink(fd.path(), ec) == target) return true;
  }
  return false;
}

// A take whose rows cannot be written ends, and its sound ends with it: the sound file is
// closed, not kept open and written on (the rows go through a link to /dev/full).
TEST(TakeSound, EndsWhenItsTakeFailsToWrite) {
  test::TempDir dir;
  fs::create_symlink("/dev/full", dir.path() / "take.csv");
  TakeSound sound(kRate);
  TakeRecorder recorder("clip", 50ms, std::nullopt, &sound);
  recorder.start(dir.path() / "take.csv");
  ASSERT_TRUE(test::eventually([&] { return recorder.error().has_value(); }, 10s));
  EXPECT_NE(recorder.error()->find("No space left on device"), std::string::npos) << *recorder.error();
  ASSERT_TRUE(fs::exists(dir.path() / "take.wav")) << "the take began with its sound";
  EXPECT_FALSE(open_here(dir.path() / "take.wav")) << "the sound file was closed with the take";
}

// A take recorded with [voice] keeps its sound beside it, on its rows' timeline, and trains a
// voice model: the generated clip with a sound track of noise bursts muxed in by ffmpeg.
/// The generated talking face with a sound: noise in bursts 2.5 times a second, 16 kHz.
void write_clip_with_sound(const fs::path& clip) {
  const test::CommandRun mux = test::run_command(fmt::format(
      "ffmpeg -loglevel error -i {} -f lavfi -i \"aevalsrc=exprs='(random(0)*2-1)*0.5*pow(max(0\\,sin(2*PI*2.5*t))"
      "\\,2)':d=10:s=16000\" -map 0:v -map 1:a -c:v copy -c:a pcm_s16le -shortest {} 2>&1",
      test::kClip.string(), clip.string()));
  ASSERT_EQ(mux.exit_code, 0) << mux.output;
}

TEST(TakeSound, TheDaemonsTakeCarriesItsSoundAndTrainsAVoice) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  test::TempDir dir;
  const fs::path clip = dir.path() / "talking.avi", takes = dir.path() / "takes";
  ASSERT_NO_FATAL_FAILURE(write_clip_with_sound(clip));
  VoiceModel model = constant_model();
  const fs::path model_file = dir.path() / "performer.lpv";
  save_voice_model_file(model_file, model);
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << fmt::format(
      "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\nreal_time = true\n[status]\nprint_interval_ms = 0\n"
      "[recording]\ndir = \"{}\"\n[voice]\nenabled = true\nmodel = \"{}\"\ninput = \"sim\"\n",
      test::kModel.string(), clip.string(), takes.string(), model_file.string());
  {
    test::DaemonProcess daemon(config, dir.path() / "daemon.txt", "--record --frames 120");
    ASSERT_EQ(daemon.wait(60s), 0) << daemon.log();
  }
  fs::path take;
  for (const auto& entry : fs::directory_iterator(takes))
    if (entry.path().extension() == ".csv") take = entry.path();
  ASSERT_FALSE(take.empty());
  const fs::path wav = fs::path(take).replace_extension(".wav");
  ASSERT_TRUE(fs::exists(wav));

  // The file's sample k was captured at the first row's capture time + k / rate. The replay's
  // start on the monotonic clock: each row's capture time less its place in the clip, the
  // earliest (a frame is captured once it is due, later when the machine is busy); the clip's
  // sound plays on that timeline.
  const CsvTable rows = read_csv_table(take);
  const std::vector<double> media = numeric_column(rows, "time_s"), captured = numeric_column(rows, "capture_time_ns");
  double replay_start_ns = INFINITY;
  for (std::size_t r = 0; r < media.size(); ++r)
    replay_start_ns = std::min(replay_start_ns, captured[r] - media[r] * 1e9);
  const DecodedAudio recorded = decode_audio(wav, kRate), original = decode_audio(clip, kRate);
  const double take_s = (captured.back() - captured.front()) * 1e-9;
  EXPECT_NEAR(recorded.samples.size() / static_cast<double>(kRate), take_s, 0.02)
      << "sound as long as the rows (two blocks)";
  const double first_row_media_s = (captured.front() - replay_start_ns) * 1e-9;
  const auto expected = static_cast<std::int64_t>(std::llround((first_row_media_s - original.start_s) * kRate));
  constexpr std::int64_t kWindow = kRate, kSearch = kRate / 8;  // 1 s compared, lags within 125 ms
  ASSERT_GE(static_cast<std::int64_t>(recorded.samples.size()), kWindow);
  std::int64_t best_lag = 0;
  double best = -1;
  for (std::int64_t lag = std::max<std::int64_t>(0, expected - kSearch); lag <= expected + kSearch; ++lag) {
    if (lag + kWindow > static_cast<std::int64_t>(original.samples.size())) break;
    double dot = 0;
    for (std::int64_t k = 0; k < kWindow; ++k)
      dot += recorded.samples[static_cast<std::size_t>(k)] * original.samples[static_cast<std::size_t>(lag + k)];
    if (dot > best) best = dot, best_lag = lag;
  }
  EXPECT_LE(std::abs(best_lag - expected), kBlock) << "the sound keeps to the rows within one 10 ms block";
  RecordProperty("take_sound_offset_samples", static_cast<int>(best_lag - expected));

  const test::CommandRun train = test::run_command(
      fmt::format("{} voice train --out {} --hidden 0 --cepstra 4 --past-ms 40 --lookahead-ms 20 {} 2>&1",
                  test::kLipdrive, (dir.path() / "trained.lpv").string(), take.string()));
  EXPECT_EQ(train.exit_code, 0) << train.output;
  EXPECT_TRUE(fs::exists(dir.path() / "trained.lpv")) << train.output;
  // A take without its sound is named.
  fs::remove(wav);
  const test::CommandRun alone = test::run_command(
      fmt::format("{} voice train --out {} {} 2>&1", test::kLipdrive, (dir.path() / "x.lpv").string(), take.string()));
  EXPECT_EQ(alone.exit_code, 66) << alone.output;
  EXPECT_NE(alone.output.find(wav.string() + ": no such take sound"), std::string::npos) << alone.output;
}

// A looping replay of a camera on its side ([camera] rotation) plays its clip's sound on the
// same loop: the replay's length reaches the sound through the shared clock, whatever wraps the
// camera (the daemon once took it by casting its camera to the replay, which the turned camera
// is not: undefined behaviour at start).
TEST(TakeSound, AReplayTurnedUprightLoopsItsSoundWithItsPicture) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  test::TempDir dir;
  const fs::path clip = dir.path() / "talking.avi";
  ASSERT_NO_FATAL_FAILURE(write_clip_with_sound(clip));
  const fs::path model_file = dir.path() / "performer.lpv", config = dir.path() / "lipdrive.toml";
  save_voice_model_file(model_file, constant_model());
  std::ofstream(config) << fmt::format(
      "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\nreal_time = true\nreplay_fps = 0\nloop = true\nrotation = 90\n"
      "[status]\nprint_interval_ms = 0\n[voice]\nenabled = true\nmodel = \"{}\"\ninput = \"sim\"\n",
      test::kModel.string(), clip.string(), model_file.string());
  test::DaemonProcess daemon(config, dir.path() / "daemon.txt", "--frames 20");
  ASSERT_EQ(daemon.wait(60s), 0) << daemon.log();
  EXPECT_NE(daemon.log().find("voice from sim:" + clip.string()), std::string::npos) << daemon.log();
}

// ---- a voice that cannot be heard: the daemon drives from the video ----------------------

class VoiceInputTest : public ::testing::Test {
 protected:
  /// Runs `lipdrive run` for 20 frames with [voice] `voice_keys` on `clip` and returns its log;
  /// it must exit 0 having driven from the video.
  std::string run_daemon(const std::string& voice_keys, const fs::path& clip = test::kClip) {
    const fs::path config = dir_.path() / "lipdrive.toml";
    std::ofstream(config) << fmt::format(
        "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\nreal_time = true\nloop = true\n"
        "[status]\nprint_interval_ms = 0\n[voice]\nenabled = true\n{}\n",
        test::kModel.string(), clip.string(), voice_keys);
    test::DaemonProcess daemon(config, dir_.path() / "daemon.txt", "--frames 20");
    EXPECT_EQ(daemon.wait(60s), 0) << daemon.log();
    const std::string log = daemon.log();
    EXPECT_EQ(log.find("voice from"), std::string::npos) << "no voice room runs\n" << log;
    EXPECT_NE(log.find("the drive follows the video alone"), std::string::npos) << log;
    return log;
  }
  /// `lipdrive check-config` on the file run_daemon() wrote.
  test::CommandRun check_config() {
    return test::run_command(std::string(test::kLipdrive) + " check-config " +
                             (dir_.path() / "lipdrive.toml").string());
  }
  fs::path model_file(const VoiceModel& model, const std::string& name) {
    const fs::path file = dir_.path() / name;
    save_voice_model_file(file, model);
    return file;
  }

  test::TempDir dir_;
};

TEST_F(VoiceInputTest, ADamagedVoiceModelIsNamedAndTheVideoDrives) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const fs::path model = model_file(constant_model(), "damaged.lpv");
  {
    std::fstream file(model, std::ios::in | std::ios::out | std::ios::binary);
    file.seekp(40);
    file.put('\x7f');
  }
  const std::string log = run_daemon(fmt::format("model = \"{}\"", model.string()));
  EXPECT_NE(log.find("voice: " + model.string() + ":"), std::string::npos) << log;
  // check-config reads it as the daemon does, and says what the daemon would run without.
  const test::CommandRun check = check_config();
  EXPECT_EQ(check.exit_code, 65) << check.output;
  EXPECT_NE(check.output.find(model.string() + ":"), std::string::npos) << check.output;
}

TEST_F(VoiceInputTest, AVoiceModelForAnotherSampleRateIsNamedAndTheVideoDrives) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const fs::path model = model_file(constant_model(8000), "8k.lpv");
  const std::string log = run_daemon(fmt::format("model = \"{}\"\nsample_rate = 16000", model.string()));
  EXPECT_NE(log.find(model.string() + ": the model was trained on sound at 8000 Hz, the input delivers 16000 Hz"),
            std::string::npos)
      << log;
  const test::CommandRun check = check_config();
  EXPECT_EQ(check.exit_code, 78) << check.output;
  EXPECT_NE(
      check.output.find("key voice.sample_rate: " + model.string() + ": the model was trained on sound at 8000 Hz"),
      std::string::npos)
      << check.output;
}

TEST_F(VoiceInputTest, AClipWithoutSoundIsNamedAndTheVideoDrives) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const fs::path model = model_file(constant_model(), "performer.lpv");
  const std::string log = run_daemon(fmt::format("model = \"{}\"\ninput = \"sim\"", model.string()));
  EXPECT_NE(log.find(test::kClip.string() + ": no audio track"), std::string::npos) << log;
}

TEST_F(VoiceInputTest, AnUnknownSoundCardIsNamedAndTheVideoDrivesUntilItOpens) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const fs::path model = model_file(constant_model(), "performer.lpv");
  const fs::path config = dir_.path() / "lipdrive.toml";
  std::ofstream(config) << fmt::format(
      "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\nreal_time = true\nloop = true\n"
      "[status]\nprint_interval_ms = 200\n[voice]\nenabled = true\nmodel = \"{}\"\ninput = \"alsa\"\n"
      "device = \"lipdrive_no_such_device\"\n",
      test::kModel.string(), test::kClip.string(), model.string());
  test::DaemonProcess daemon(config, dir_.path() / "daemon.txt", "--frames 40");
  EXPECT_EQ(daemon.wait(60s), 0) << daemon.log();
  const std::string log = daemon.log();
  EXPECT_NE(log.find("voice input alsa:lipdrive_no_such_device: cannot open the capture device"), std::string::npos)
      << log;
  EXPECT_NE(log.find("the drive follows the video alone until it opens"), std::string::npos) << log;
  EXPECT_NE(log.find("drive video"), std::string::npos) << "the status line\n" << log;
  // check-config opens it once and names it.
  const test::CommandRun check = test::run_command(std::string(test::kLipdrive) + " check-config " + config.string());
  EXPECT_EQ(check.exit_code, 78) << check.output;
  EXPECT_NE(check.output.find("key voice.device: alsa:lipdrive_no_such_device"), std::string::npos) << check.output;
}

}  // namespace
}  // namespace lipdrive
