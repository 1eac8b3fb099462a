// The calibration round trip on a real talking face: `lipdrive calibrate` on a GRID take,
// then the pipeline drives an open channel with that profile. The performer's mouth must use
// the whole channel and come back to rest in the closing silence. With the ICT head, the
// calibration fits the performer's identity, and `lipdrive process --config` fits on it.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "core/model_format.hpp"
#include "core/statistics.hpp"
#include "daemon_process.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "firmware_app/daemon/pipeline.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "fixture_paths.hpp"
#include "shared_predictor.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <mutex>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

using test::kModel;
const fs::path kTake = test::shared_fixtures() / "grid" / "bbaf2n.mpg";
constexpr std::uint64_t kFinalSilenceFrom = 54;  // bbaf2n.align: "53000 74500 sil", frames 54..74

/// The open channel's value for every processed frame, by source frame.
class OpenChannelByFrame : public Output {
 public:
  void publish(const DriveFrame& frame) override {
    if (!frame.new_result || !(frame.status & kStatusTracking)) return;
    std::lock_guard lock(mutex_);
    values_[frame.sequence] = frame.values[0];
  }
  std::string describe() const override { return "open by frame"; }
  std::map<std::uint64_t, double> values() const {
    std::lock_guard lock(mutex_);
    return values_;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::uint64_t, double> values_;
};

TEST(CalibrateGrid, ProfileFromATakeSpansTheChannelAndRestsInSilence) {
  LIPDRIVE_SKIP_WITHOUT_SHARED(kTake);
  const fs::path dir = fs::temp_directory_path() / fmt::format("lipdrive_test_calibrate_{}", ::getpid());
  fs::create_directories(dir);
  const fs::path config = dir / "lipdrive.toml";
  std::ofstream(config) << fmt::format(
      "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n[performer]\nprofiles_dir = \"{}\"\n", kModel.string(),
      kTake.string(), dir.string());

  // The first 15 tracked frames are the opening silence: the neutral pose.
  const std::string command =
      fmt::format("{} calibrate --config {} --performer grid --input {} --neutral-frames 15 2>&1", test::kLipdrive,
                  config.string(), kTake.string());
  std::FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  for (char buffer[256]; std::fgets(buffer, sizeof buffer, pipe);) output += buffer;
  ASSERT_EQ(::pclose(pipe), 0) << output;
  EXPECT_NE(output.find("performer grid"), std::string::npos) << output;
  const PerformerProfile profile = load_profile(dir / "grid.toml", "grid");
  EXPECT_TRUE(profile.calibrated);
  ASSERT_TRUE(profile.face_indices.has_value()) << "the neutral face's indices (docs/method.md 6)";
  EXPECT_GT((*profile.face_indices)[kVerticalMouthHeightIndex], 5);
  EXPECT_NE(output.find("vertical mouth height"), std::string::npos) << output;
  EXPECT_GT(profile.open.max, profile.open.min + 0.1) << output;

  // No ease or hold, so the channel shows the calibrated signal itself.
  PipelineSettings settings;
  settings.channels = {ChannelSpec{.name = "open", .signal = Signal::kOpen, .out_min = 0, .out_max = 1, .neutral = 0}};
  settings.safety = {.hold_ns = 0, .ease_ns = 0};
  SimulatedCameraOptions take;
  take.input = kTake;
  take.real_time = true;  // no frame is dropped at 25 fps
  static const MorphableModel model = load_model_file(kModel);
  DriveControl control;
  Pipeline pipeline(
      std::make_unique<SimulatedCamera>(take),
      std::make_unique<FrameProcessor>(model, kDefaultLandmarkSet, FitSettings{}, test::shared_predictor()), settings,
      control);
  pipeline.set_profile(profile);
  OpenChannelByFrame open;
  pipeline.add_output(open);
  pipeline.start();
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (!pipeline.finished() && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(20ms);
  pipeline.stop();

  const std::map<std::uint64_t, double> values = open.values();
  ASSERT_GE(values.size(), 70u) << "frames tracked and driven";
  double lowest = 1, highest = 0, silence_sum = 0, silence_max = 0;
  int silence_frames = 0;
  for (const auto& [frame, value] : values) {
    lowest = std::min(lowest, value);
    highest = std::max(highest, value);
    if (frame >= kFinalSilenceFrom) {
      silence_sum += value;
      silence_max = std::max(silence_max, value);
      ++silence_frames;
    }
  }
  RecordProperty("open_span", fmt::format("{:.3f}", highest - lowest));
  RecordProperty("final_silence_mean", fmt::format("{:.3f}", silence_sum / silence_frames));
  RecordProperty("final_silence_max", fmt::format("{:.3f}", silence_max));
  EXPECT_GE(highest - lowest, 0.8);
  ASSERT_GT(silence_frames, 15);
  EXPECT_LE(silence_max, 0.1) << "mean " << silence_sum / silence_frames;
  fs::remove_all(dir);
}

/// The median fit quality of the tracked rows of a `lipdrive process` table.
double median_quality(const fs::path& table) {
  std::vector<double> quality;
  for (const double q : numeric_column(read_csv_table(table), "quality"))
    if (std::isfinite(q)) quality.push_back(q);
  return quality.empty() ? 0.0 : median(quality);
}

TEST(CalibrateGrid, TheIctHeadKeepsThePerformersIdentityAndTheFitUsesIt) {
  LIPDRIVE_SKIP_WITHOUT_SHARED(kTake);
  const fs::path ict = fs::path(test::kModelDir) / "ict_face_light.lpm";
  const fs::path dir = fs::temp_directory_path() / fmt::format("lipdrive_test_calibrate_ict_{}", ::getpid());
  fs::create_directories(dir);
  // Calibrated without a performer named (the profile does not exist yet), then fitted with one
  // and without.
  const std::string model_lines = fmt::format(
      "[model]\nfile = \"{}\"\nlandmark_set = \"F5\"\n[camera]\ninput = \"{}\"\n", ict.string(), kTake.string());
  std::ofstream(dir / "calibrate.toml") << model_lines
                                        << fmt::format("[performer]\nprofiles_dir = \"{}\"\n", dir.string());
  const fs::path config = dir / "lipdrive.toml";
  std::ofstream(config) << model_lines
                        << fmt::format("[performer]\nname = \"grid\"\nprofiles_dir = \"{}\"\n", dir.string());
  std::ofstream(dir / "mean.toml") << model_lines;

  const test::CommandRun calibrate =
      test::run_command(fmt::format("{} calibrate --config {} --performer grid --input {} --neutral-frames 15",
                                    test::kLipdrive, (dir / "calibrate.toml").string(), kTake.string()));
  ASSERT_EQ(calibrate.exit_code, 0) << calibrate.output;
  EXPECT_THAT(calibrate.output, ::testing::HasSubstr("identity: 20 components from 15 neutral frames"));
  const PerformerProfile profile = load_profile(dir / "grid.toml", "grid");
  ASSERT_TRUE(profile.identity.has_value()) << calibrate.output;
  EXPECT_EQ(profile.identity->components, 20);
  EXPECT_EQ(profile.identity->model_fingerprint, identity_fingerprint(load_model_file(ict)));
  EXPECT_GT(profile.identity->vector(20).norm(), 0.1) << "a face other than the mean";

  // The same take fitted on the performer's identity and on the mean face.
  for (const auto& [settings, table] :
       {std::pair{config, dir / "grid.csv"}, std::pair{dir / "mean.toml", dir / "mean.csv"}}) {
    const test::CommandRun process = test::run_command(fmt::format(
        "{} process {} --config {} --out {}", test::kLipdrive, kTake.string(), settings.string(), table.string()));
    ASSERT_EQ(process.exit_code, 0) << process.output;
  }
  const double with_identity = median_quality(dir / "grid.csv"), mean_face = median_quality(dir / "mean.csv");
  RecordProperty("ict_quality_identity", fmt::format("{:.4f}", with_identity));
  RecordProperty("ict_quality_mean_face", fmt::format("{:.4f}", mean_face));
  fmt::print("ICT head on {}: median fit quality {:.4f} on the performer's identity, {:.4f} on the mean face\n",
             kTake.filename().string(), with_identity, mean_face);
  EXPECT_GT(with_identity, mean_face) << "the performer's identity explains the landmarks better";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace lipdrive
