// The voice room ([voice], docs/voice.md): the microphone's blocks through the voice model on a
// thread of its own, the newest prediction published latest-wins without a heap allocation per
// block; and a voice that cannot be heard (a damaged model, one for another sample rate, a
// clip without sound, an unknown sound card) leaves `lipdrive run` driving from the video.
#include "allocation_counter.hpp"
#include "build_paths.hpp"
#include "command_run.hpp"
#include "daemon_process.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/voice_room.hpp"
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
}

TEST_F(VoiceInputTest, AVoiceModelForAnotherSampleRateIsNamedAndTheVideoDrives) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  const fs::path model = model_file(constant_model(8000), "8k.lpv");
  const std::string log = run_daemon(fmt::format("model = \"{}\"\nsample_rate = 16000", model.string()));
  EXPECT_NE(log.find(model.string() + ": the model was trained on sound at 8000 Hz, the input delivers 16000 Hz"),
            std::string::npos)
      << log;
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
