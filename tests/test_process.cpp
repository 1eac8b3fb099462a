// Acceptance tests of `lipdrive process`: accuracy on the generated talking face, lip
// closures on real GRID speech, and bad input that must fail cleanly.
#include "build_paths.hpp"
#include "command_run.hpp"
#include "core/arkit.hpp"
#include "core/calibration.hpp"
#include "core/face_tracker.hpp"
#include "core/metrics.hpp"
#include "core/statistics.hpp"
#include "core/viseme_weights.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "fixture_paths.hpp"
#include "sim/face_faults.hpp"
#include "variable_rate_clip.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>
#include <random>
#include <string>
#include <sys/stat.h>
#include <sys/wait.h>
#include <tuple>
#include <unistd.h>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

const fs::path kGridDir = test::shared_fixtures() / "grid";
const fs::path kFixtureDir = test::kFixtureDir;

struct ProcessRun {
  int exit_code = -1;
  std::string stderr_text;
};

// Runs `lipdrive process ARGS` and returns its exit code and stderr (kept in `dir`).
ProcessRun run_process(const std::string& args, const fs::path& dir) {
  const fs::path err = dir / "stderr.txt";
  const std::string command = std::string(test::kLipdrive) + " process " + args + " 2>" + err.string();
  const int status = std::system(command.c_str());
  ProcessRun run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(err);
  run.stderr_text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  fs::remove(err);
  return run;
}

/// The frames of a video, as OpenCV's reader counts them.
std::size_t frame_count(const fs::path& video) {
  return static_cast<std::size_t>(cv::VideoCapture(video.string()).get(cv::CAP_PROP_FRAME_COUNT));
}

class ProcessTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lipdrive_test_process_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::permissions(dir_, fs::perms::owner_all, fs::perm_options::add, ec);
    for (const auto& entry : fs::recursive_directory_iterator(dir_, ec))
      fs::permissions(entry.path(), fs::perms::owner_all, fs::perm_options::add, ec);
    fs::remove_all(dir_, ec);
  }
  fs::path dir_;
};

std::vector<double> scaled(std::vector<double> v) {
  const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
  const double min = *lo, range = *hi - *lo;
  for (double& x : v) x = range > 0 ? (x - min) / range : 0;
  return v;
}

// The generated head, whose renders the clip and its truth are, and the daemon's default, the
// ICT head on the identity it fits of its own (AutoIdentity, fitted before the take is measured):
// its fitted mouth follows the truth within the same bounds on every frame.
TEST_F(ProcessTest, GeneratedTalkingFaceFollowsItsTruth) {
  const fs::path video = kFixtureDir / "talking_face.avi", truth_csv = kFixtureDir / "talking_face_truth.csv";
  LIPDRIVE_REQUIRE_BUILT(video);
  LIPDRIVE_REQUIRE_BUILT(truth_csv);
  const CsvTable truth = read_csv_table(truth_csv);
  const auto truth_width = numeric_column(truth, "width_2d"), truth_height = numeric_column(truth, "height_2d");
  for (const auto& [name, options] :
       {std::pair<std::string, std::string>{"generated",
                                            fmt::format("--model {} --landmark-set F4", test::kModel.string())},
        {"ict", ""}}) {
    SCOPED_TRACE(name);
    const fs::path out = dir_ / (name + ".csv");
    const ProcessRun run = run_process(fmt::format("{} {} --out {}", video.string(), options, out.string()), dir_);
    ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
    const CsvTable output = read_csv_table(out);
    ASSERT_EQ(output.rows.size(), truth.rows.size());
    for (const char* column : {"height_2d", "height_fit"}) {
      const SeriesAgreement a = compare_series(truth_height, numeric_column(output, column));
      RecordProperty(fmt::format("{}_{}_rmse_scaled_r", name, column),
                     fmt::format("{:.3f} {:.3f}", a.rmse_scaled, a.pearson_r));
      EXPECT_EQ(a.pairs_used, static_cast<int>(truth.rows.size())) << column << ": untracked frames";
      EXPECT_LE(a.rmse_scaled, 0.08) << column;
      EXPECT_GE(a.pearson_r, 0.9) << column;
    }
    for (const char* column : {"width_2d", "width_fit"}) {
      const SeriesAgreement a = compare_series(truth_width, numeric_column(output, column));
      RecordProperty(fmt::format("{}_{}_rmse_scaled_r", name, column),
                     fmt::format("{:.3f} {:.3f}", a.rmse_scaled, a.pearson_r));
      EXPECT_LE(a.rmse_scaled, 0.10) << column;
    }
  }
}

std::string file_text(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// `process --config` builds the tracker and the fit from the daemon's file, through the
// daemon's factory: the file's settings change the output exactly as they change the rig's.
// (process_with writes its text after a [model] header; a [tracker] table may follow it.)
TEST_F(ProcessTest, TheDaemonsConfigurationSetsTheFit) {
  const fs::path video = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(video);
  const auto process_with = [&](const std::string& name, const std::string& model_table) {
    const fs::path config = dir_ / (name + ".toml"), out = dir_ / (name + ".csv");
    std::ofstream(config) << "[model]\n" << model_table;
    const ProcessRun run =
        run_process(video.string() + " --config " + config.string() + " --out " + out.string(), dir_);
    EXPECT_EQ(run.exit_code, 0) << run.stderr_text;
    return file_text(out);
  };
  const fs::path defaults_out = dir_ / "defaults.csv";
  ASSERT_EQ(run_process(video.string() + " --out " + defaults_out.string(), dir_).exit_code, 0);
  const std::string defaults = file_text(defaults_out);
  ASSERT_FALSE(defaults.empty());
  EXPECT_EQ(process_with("same", "iterations = 10\nlandmark_set = \"F5\"\nauto_identity_frames = 20\n"), defaults)
      << "the defaults are the daemon's defaults";
  EXPECT_NE(process_with("one_iteration", "iterations = 1\n"), defaults) << "[model] iterations reaches the fit";
  EXPECT_NE(process_with("no_jaw_line", "landmark_set = \"F4\"\n"), defaults) << "[model] landmark_set too";
  EXPECT_NE(process_with("mean_face", "auto_identity_frames = 0\n"), defaults) << "and auto_identity_frames";
  EXPECT_EQ(process_with("face_at_least_80px", "[tracker]\nmin_face_px = 80\n"), defaults);
  const fs::path wide = dir_ / "wide_faces_only.toml";
  std::ofstream(wide) << "[tracker]\nmin_face_px = 4096\n";
  const ProcessRun none = run_process(video.string() + " --config " + wide.string(), dir_);
  EXPECT_NE(none.stderr_text.find("no face"), std::string::npos)
      << "[tracker] min_face_px reaches the tracker: no face that wide in the clip\n"
      << none.stderr_text;

  const fs::path bad = dir_ / "bad.toml";
  std::ofstream(bad) << "[model]\niterations = 0\n";
  const ProcessRun run = run_process(video.string() + " --config " + bad.string(), dir_);
  EXPECT_EQ(run.exit_code, 78) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("key model.iterations"), std::string::npos) << run.stderr_text;
}

// The 52 ARKit columns, in Apple's order after the visemes: from the signals for the generated
// (pose-PCA) head, from the expression fit for the ICT head.
TEST_F(ProcessTest, ArkitColumnsComeFromTheSignalsOrTheFit) {
  const fs::path video = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(video);
  const fs::path pca_out = dir_ / "pca.csv", ict_out = dir_ / "ict.csv";
  ASSERT_EQ(run_process(fmt::format("{} --model {} --landmark-set F4 --out {}", video.string(), test::kModel.string(),
                                    pca_out.string()),
                        dir_)
                .exit_code,
            0);
  const fs::path ict = fs::path(test::kModelDir) / "ict_face_light.lpm";
  const ProcessRun run = run_process(
      fmt::format("{} --model {} --landmark-set F5 --out {}", video.string(), ict.string(), ict_out.string()), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  const CsvTable pca = read_csv_table(pca_out), fitted = read_csv_table(ict_out);
  const auto viseme_w = std::find(pca.header.begin(), pca.header.end(), "viseme_W");
  ASSERT_NE(viseme_w, pca.header.end());
  for (std::size_t a = 0; a < kArkitNames.size(); ++a)
    ASSERT_EQ(viseme_w[static_cast<std::ptrdiff_t>(a + 1)], "arkit_" + std::string(kArkitNames[a]));
  EXPECT_EQ(fitted.header, pca.header);

  // Without expression shapes: jawOpen = open under the default ranges, mouthClose = seal, and
  // only the four mouth weights move.
  const PerformerProfile defaults;
  const auto open = numeric_column(pca, "open"), seal = numeric_column(pca, "seal"),
             jaw = numeric_column(pca, "arkit_jawOpen"), close = numeric_column(pca, "arkit_mouthClose");
  for (std::size_t row = 0; row < open.size(); ++row) {
    ASSERT_FALSE(std::isnan(jaw[row])) << "every frame of the clip is tracked";
    EXPECT_NEAR(jaw[row], defaults.open.scale(open[row]), 2e-4) << row;
    EXPECT_NEAR(close[row], seal[row], 2e-4) << row;
  }
  const auto highest = [](const CsvTable& table, std::string_view name) {
    double most = 0;  // untracked frames (NaN) skipped
    for (const double w : numeric_column(table, "arkit_" + std::string(name)))
      most = std::max(most, std::isnan(w) ? 0 : w);
    return most;
  };
  EXPECT_GT(highest(pca, "jawOpen"), 0.5);
  for (const char* other : {"mouthSmileLeft", "browInnerUp", "eyeBlinkRight"})
    EXPECT_EQ(highest(pca, other), 0) << other;

  // The ICT head: the weights are the fit's, more than the four mouth weights move, and the
  // shapes 68 landmarks cannot show read 0. Without a profile the processor fits an identity
  // of its own on the first 20 tracked frames ([model] auto_identity_frames); offline the take
  // is all there, so `process` fits it first and measures every frame on it: the first 20 rows
  // read as the later rows of the same mouth (the daemon, live, holds them at 0: they were 0
  // here too before, and jawOpen's r over all rows 0.77), and jawOpen follows the opening over
  // all rows (r 0.98; on the mean face, `auto_identity_frames = 0`, r is 0.09 after row 20).
  EXPECT_NE(run.stderr_text.find("identity: fitted from the first 20 tracked frames"), std::string::npos)
      << run.stderr_text;
  const auto height = numeric_column(fitted, "height_2d");
  const auto jaw_open = numeric_column(fitted, "arkit_jawOpen");
  ASSERT_GT(height.size(), 130u);
  // The clip rests with its lips together on rows 5-15 and again on rows 120-130.
  const auto mean_over = [](const std::vector<double>& v, std::size_t first, std::size_t last) {
    return std::accumulate(v.begin() + first, v.begin() + last + 1, 0.0) / static_cast<double>(last - first + 1);
  };
  RecordProperty("ict_jawOpen_rest_first_later",
                 fmt::format("{:.3f} {:.3f}", mean_over(jaw_open, 5, 15), mean_over(jaw_open, 120, 130)));
  EXPECT_NEAR(mean_over(jaw_open, 5, 15), mean_over(jaw_open, 120, 130), 0.02)
      << "the first rows on the take's identity";
  // There the pixels see the lips touch (seal about 0.98) while the landmarks read them 0.09 d
  // apart and the fit opens the jaw to match (jawOpen about 0.37): mouthClose closes the lips
  // over that jaw, so a rig that opens its lips by jawOpen - mouthClose keeps them shut.
  const auto mouth_close = numeric_column(fitted, "arkit_mouthClose"), ict_seal = numeric_column(fitted, "seal");
  for (std::size_t row = 5; row <= 15; ++row) {
    ASSERT_GT(ict_seal[row], 0.9) << row;
    EXPECT_LT(jaw_open[row] - mouth_close[row], 0.02 * jaw_open[row] + 1e-3) << row;
  }
  const SeriesAgreement jaw_fit = compare_series(height, jaw_open);
  RecordProperty("ict_auto_identity_jawOpen_r_height_2d", fmt::format("{:.3f}", jaw_fit.pearson_r));
  EXPECT_GT(jaw_fit.pearson_r, 0.9);
  {
    const fs::path config = dir_ / "mean_face.toml", out = dir_ / "mean_face.csv";
    std::ofstream(config) << fmt::format("[model]\nfile = \"{}\"\nlandmark_set = \"F5\"\nauto_identity_frames = 0\n",
                                         ict.string());
    const ProcessRun mean_face =
        run_process(fmt::format("{} --config {} --out {}", video.string(), config.string(), out.string()), dir_);
    ASSERT_EQ(mean_face.exit_code, 0) << mean_face.stderr_text;
    EXPECT_EQ(mean_face.stderr_text.find("identity: fitted"), std::string::npos) << "off: the mean face throughout";
    EXPECT_GT(numeric_column(read_csv_table(out), "arkit_jawOpen")[0], 0.1) << "the mean face's weights, not held";
  }
  // Its protrusion is measured from the face's own rest (the take's identity and its rest
  // point): the clip starts at rest and reads about 0 there, where the mean face, whose
  // difference from this face goes into the expression weights, reads -0.09.
  std::vector<double> first_protrusion = numeric_column(fitted, "protrusion_3d");
  first_protrusion.resize(20);
  RecordProperty("ict_protrusion_3d_median_first_20", fmt::format("{:.4f}", median(first_protrusion)));
  EXPECT_LT(std::abs(median(first_protrusion)), 0.02);
  for (const char* held : {"cheekPuff", "tongueOut", "eyeLookInLeft", "eyeLookUpRight"})
    EXPECT_EQ(highest(fitted, held), 0) << held;
  int moving = 0;
  for (const std::string_view name : kArkitNames) moving += highest(fitted, name) > 0.05;
  EXPECT_GT(moving, 4);

  // Its visemes are its ARKit weights as fitted through the table and the seal
  // (core/viseme_weights.hpp), to the CSV's 4 decimals, on the rows whose mouthClose is the
  // fit's (where the seal closed the lips, seal x jawOpen, the fitted one is not in the CSV);
  // the generated head's come from its poses.
  std::vector<std::vector<double>> arkit_columns, viseme_columns;
  for (const std::string_view name : kArkitNames)
    arkit_columns.push_back(numeric_column(fitted, "arkit_" + std::string(name)));
  for (const std::string_view name : kVisemeNames)
    viseme_columns.push_back(numeric_column(fitted, "viseme_" + std::string(name)));
  const auto fitted_seal = numeric_column(fitted, "seal");
  double most = 0;
  int compared = 0;
  const std::size_t jaw_column = *arkit_index("jawOpen"), close_column = *arkit_index("mouthClose");
  for (std::size_t row = 0; row < fitted_seal.size(); ++row) {
    if (std::isnan(fitted_seal[row])) continue;
    const double sealed = fitted_seal[row] * arkit_columns[jaw_column][row];
    if (sealed > 1e-4 && std::abs(arkit_columns[close_column][row] - sealed) < 2e-4) continue;
    ++compared;
    ArkitWeights arkit;
    for (int a = 0; a < kNumArkit; ++a) arkit[static_cast<std::size_t>(a)] = static_cast<float>(arkit_columns[a][row]);
    const VisemeWeights expected = visemes_from_arkit(arkit, fitted_seal[row]);
    for (int v = 0; v < kNumVisemes; ++v) {
      EXPECT_NEAR(viseme_columns[v][row], expected[static_cast<std::size_t>(v)], 3e-3) << kVisemeNames[v] << " " << row;
      most = std::max(most, viseme_columns[v][row]);
    }
  }
  EXPECT_GE(compared, 50) << "of " << fitted_seal.size() << " (59 rows of 213 on 12-07: the clip's lips touch on most)";
  EXPECT_GT(most, 0.5) << "the ICT head's visemes move";
}

TEST_F(ProcessTest, SideInputAddsTheSideViewProtrusion) {
  const fs::path front = kFixtureDir / "talking_face.avi", side = kFixtureDir / "side_view.avi",
                 truth_csv = kFixtureDir / "side_view_truth.csv";
  LIPDRIVE_REQUIRE_BUILT(front);
  LIPDRIVE_REQUIRE_BUILT(side);
  const fs::path out = dir_ / "with_side.csv";
  const ProcessRun run =
      run_process(fmt::format("{} --side {} --out {}", front.string(), side.string(), out.string()), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  const CsvTable output = read_csv_table(out);
  ASSERT_EQ(output.header.back(), "protrusion_side");
  const CsvTable truth = read_csv_table(truth_csv);
  // The side clip is the shorter one: its rows pair with the first front rows, frame for frame.
  std::vector<double> measured = numeric_column(output, "protrusion_side");
  measured.resize(truth.rows.size());
  const SeriesAgreement a = compare_series(numeric_column(truth, "protrusion_truth"), measured);
  RecordProperty("protrusion_side_rmse_scaled", std::to_string(a.rmse_scaled));
  RecordProperty("protrusion_side_r", std::to_string(a.pearson_r));
  EXPECT_EQ(a.pairs_used, static_cast<int>(truth.rows.size())) << "every side frame measured";
  EXPECT_GE(a.pearson_r, 0.95);
  EXPECT_LE(a.rmse_scaled, 0.1);
}

TEST_F(ProcessTest, ASideRecordingOnItsSideIsTurnedUprightFirst) {
  const fs::path front = kFixtureDir / "talking_face.avi", side = kFixtureDir / "side_view.avi";
  LIPDRIVE_REQUIRE_BUILT(front);
  LIPDRIVE_REQUIRE_BUILT(side);
  // The side clip's first 60 frames as images, upright and turned a quarter turn anticlockwise.
  cv::VideoCapture capture(side.string());
  const fs::path upright = dir_ / "upright", sideways = dir_ / "sideways", mirrored = dir_ / "mirrored";
  for (const fs::path& folder : {upright, sideways, mirrored}) fs::create_directories(folder);
  cv::Mat bgr, turned;
  for (int i = 0; i < 60 && capture.read(bgr); ++i) {
    const std::string name = fmt::format("side{:03}.png", i);
    cv::imwrite((upright / name).string(), bgr);
    cv::rotate(bgr, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
    cv::imwrite((sideways / name).string(), turned);
    cv::flip(bgr, turned, 1);
    cv::imwrite((mirrored / name).string(), turned);
  }
  // The rig's file turns and faces the side view as its side camera would, enabled for the daemon or not
  // (the face looking left in the mirrored view).
  const fs::path turned_config = dir_ / "turned.toml", left_config = dir_ / "left.toml";
  std::ofstream(turned_config) << "[side_camera]\nrotation = 90\n";
  std::ofstream(left_config) << "[side_camera]\nfacing = \"left\"\n";
  const fs::path expected = dir_ / "upright.csv", got = dir_ / "turned.csv", configured = dir_ / "configured.csv",
                 left = dir_ / "left.csv", right = dir_ / "right.csv";
  for (const auto& [args, out] :
       {std::pair{"--side " + upright.string(), expected},
        std::pair{"--side " + sideways.string() + " --side-rotate 90", got},
        std::pair{"--side " + sideways.string() + " --config " + turned_config.string(), configured},
        std::pair{"--side " + mirrored.string() + " --config " + left_config.string(), left},
        std::pair{"--side " + upright.string() + " --config " + left_config.string() + " --side-facing right",
                  right}}) {
    const ProcessRun run = run_process(fmt::format("{} {} --out {}", front.string(), args, out.string()), dir_);
    ASSERT_EQ(run.exit_code, 0) << args << ": " << run.stderr_text;
  }
  const std::vector<double> want = numeric_column(read_csv_table(expected), "protrusion_side");
  ASSERT_GT(std::count_if(want.begin(), want.end(), [](double p) { return std::isfinite(p); }), 20);
  for (const fs::path& out : {got, configured, right}) {
    SCOPED_TRACE(out.filename().string());
    const std::vector<double> have = numeric_column(read_csv_table(out), "protrusion_side");
    ASSERT_EQ(have.size(), want.size());
    for (std::size_t i = 0; i < want.size(); ++i) {
      ASSERT_EQ(std::isfinite(have[i]), std::isfinite(want[i])) << "row " << i;
      if (std::isfinite(want[i])) {
        EXPECT_EQ(have[i], want[i]) << "row " << i;
      }
    }
  }
  const std::vector<double> have = numeric_column(read_csv_table(left), "protrusion_side");
  ASSERT_EQ(have.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_EQ(std::isfinite(have[i]), std::isfinite(want[i])) << "mirrored, row " << i;
    if (std::isfinite(want[i])) {
      EXPECT_NEAR(have[i], want[i], 1e-9) << "mirrored, row " << i;
    }
  }
}

// The lips close on "bin" and "blue" and rest closed after the sentence: in `open`, the signal
// that drives the figure (landmarks and pixels, the default configuration), and in the fitted
// height of the generated head. The ICT head's fitted height is recorded, not bounded: its lips
// close on fewer bilabials ("blue" here reads 0.26; README, scripts/fit-grid.py).
TEST_F(ProcessTest, GridSpeechClosesTheLipsOnBilabials) {
  const fs::path clip = kGridDir / "bbaf2n.mpg";
  LIPDRIVE_SKIP_WITHOUT_SHARED(clip);
  // Every frame of the clip tracked, with the configuration `options` names.
  const auto process = [&](const std::string& name, const std::string& options) {
    const fs::path out = dir_ / (name + ".csv");
    const ProcessRun run = run_process(fmt::format("{} --out {} {}", clip.string(), out.string(), options), dir_);
    EXPECT_EQ(run.exit_code, 0) << run.stderr_text;
    const CsvTable table = read_csv_table(out);
    EXPECT_EQ(table.rows.size(), 75u) << name;
    const auto tracked = numeric_column(table, "tracked");
    EXPECT_TRUE(std::all_of(tracked.begin(), tracked.end(), [](double t) { return t == 1; })) << name;
    return table;
  };
  // bbaf2n.align: "bin" frames 23-29, "blue" 29-34, final silence 53-74 (the lips settle by 56).
  const auto closures = [](const CsvTable& table, const std::string& column) {
    const auto height = scaled(numeric_column(table, column));
    const auto min_over = [&](int first, int last) {
      return *std::min_element(height.begin() + first, height.begin() + last + 1);
    };
    double silence = 0;
    for (int f = 56; f <= 74; ++f) silence += height[f];
    return std::array<double, 3>{min_over(23, 29), min_over(29, 34), silence / 19};
  };
  const auto expect_closes = [&](const CsvTable& table, const std::string& name, const std::string& column) {
    if (table.rows.size() != 75u) return;
    const auto [bin, blue, silence] = closures(table, column);
    RecordProperty(fmt::format("{}_scaled_{}_min_bin_blue", name, column), fmt::format("{:.3f} {:.3f}", bin, blue));
    RecordProperty(fmt::format("{}_scaled_{}_final_silence_mean", name, column), fmt::format("{:.3f}", silence));
    EXPECT_LE(bin, 0.2) << name << " " << column << ": lips do not close on 'bin'";
    EXPECT_LE(blue, 0.2) << name << " " << column << ": lips do not close on 'blue'";
    EXPECT_LE(silence, 0.15) << name << " " << column << ": mouth not closed in the final silence";
  };

  const CsvTable generated = process("generated", fmt::format("--model {} --landmark-set F4", test::kModel.string()));
  expect_closes(generated, "generated", "height_fit");
  const CsvTable defaults = process("default", "--include-landmarks");
  ASSERT_EQ(defaults.rows.size(), 75u);
  expect_closes(defaults, "default", "open");
  const auto [bin, blue, silence] = closures(defaults, "height_fit");
  RecordProperty("default_scaled_height_fit_min_bin_blue", fmt::format("{:.3f} {:.3f}", bin, blue));
  ASSERT_TRUE(has_column(defaults, "x67"));
  ASSERT_TRUE(has_column(defaults, "y0"));
  // The ICT head's protrusion is measured from the face's rest (its identity and rest point, the
  // first frame's until the 20th): at rest before the sentence it reads about 0, where from the
  // identity's neutral shape alone it read -0.15 (the rest point draws the lips in).
  const std::vector<double> protrusion = numeric_column(defaults, "protrusion_3d");
  std::vector<double> at_rest(protrusion.begin() + 1, protrusion.begin() + 18);
  RecordProperty("default_protrusion_3d_median_at_rest", fmt::format("{:.4f}", median(at_rest)));
  EXPECT_LT(std::abs(median(at_rest)), 0.05);
}

/// The tracked landmarks of each row (x0..x67, y0..y67); empty for an untracked row.
std::vector<Landmarks2D> landmark_rows(const CsvTable& table) {
  std::vector<Landmarks2D> rows(table.rows.size());
  const auto tracked = numeric_column(table, "tracked");
  for (int i = 0; i < kNumLandmarks; ++i) {
    const auto x = numeric_column(table, fmt::format("x{}", i)), y = numeric_column(table, fmt::format("y{}", i));
    for (std::size_t r = 0; r < rows.size(); ++r) rows[r].col(i) << x[r], y[r];
  }
  for (std::size_t r = 0; r < rows.size(); ++r)
    if (tracked[r] != 1) rows[r].setConstant(std::nan(""));
  return rows;
}

TEST_F(ProcessTest, EveryImageOfAFolderIsDetectedAfresh) {
  // Three photographs of the same face in different places, as unrelated pictures are: each
  // must be found where it is, not where the previous picture had it.
  cv::VideoCapture capture((kFixtureDir / "talking_face.avi").string());
  cv::Mat bgr, gray;
  ASSERT_TRUE(capture.read(bgr));
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  const fs::path folder = dir_ / "photos";
  fs::create_directories(folder);
  const std::vector<Eigen::Vector2d> offsets{{0, 0}, {120, 0}, {-100, 30}};
  for (std::size_t i = 0; i < offsets.size(); ++i)
    cv::imwrite((folder / fmt::format("photo{}.png", i)).string(),
                shifted_frame(gray, offsets[i].x(), offsets[i].y(), 128));

  const fs::path single = dir_ / "single.csv", all = dir_ / "all.csv";
  ProcessRun run =
      run_process((folder / "photo0.png").string() + " --include-landmarks --out " + single.string(), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  run = run_process(folder.string() + " --include-landmarks --out " + all.string(), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  const Landmarks2D reference = landmark_rows(read_csv_table(single)).at(0);
  ASSERT_TRUE(reference.allFinite()) << "the photograph alone is not tracked";
  const std::vector<Landmarks2D> rows = landmark_rows(read_csv_table(all));
  ASSERT_EQ(rows.size(), offsets.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    ASSERT_TRUE(rows[i].allFinite()) << "photo " << i << " not tracked";
    const Landmarks2D expected = reference.colwise() + offsets[i];
    const double error = (rows[i] - expected).colwise().norm().mean() / interocular_distance(expected);
    EXPECT_LT(error, 0.05) << "photo " << i;
  }
  // And measured as alone: not on the identity fitted on the photograph before it.
  const fs::path second = dir_ / "second.csv";
  run = run_process((folder / "photo1.png").string() + " --out " + second.string(), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  const CsvTable alone = read_csv_table(second), together = read_csv_table(all);
  for (const char* column : {"height_fit", "width_fit", "width_3d", "protrusion_3d", "quality"})
    EXPECT_EQ(numeric_column(together, column).at(1), numeric_column(alone, column).at(0)) << column;
}

TEST_F(ProcessTest, EveryPictureOfAFolderThatCannotBeReadIsNamed) {
  LIPDRIVE_REQUIRE_BUILT(kFixtureDir / "astronaut.png");
  const fs::path folder = dir_ / "photos";
  fs::create_directories(folder);
  fs::copy_file(kFixtureDir / "astronaut.png", folder / "face.png");
  std::ofstream(folder / "broken.jpg") << "x";
  std::ofstream(folder / "zbroken.png") << "y";
  const fs::path out = dir_ / "out.csv";
  const ProcessRun run = run_process(folder.string() + " --out " + out.string(), dir_);
  EXPECT_EQ(run.exit_code, 65) << run.stderr_text;
  for (const char* name : {"broken.jpg", "zbroken.png"})
    EXPECT_NE(run.stderr_text.find(name), std::string::npos) << name << "\n" << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("2 pictures could not be decoded"), std::string::npos) << run.stderr_text;
  EXPECT_EQ(read_csv_table(out).rows.size(), 1u) << "the picture that reads is processed";
}

TEST_F(ProcessTest, FramesOfACameraOnItsSideAreTurnedUprightFirst) {
  // Frames of the generated clip as a camera mounted a quarter turn anticlockwise records them:
  // --rotate 90 must give exactly the rows of the upright frames (the turn loses no pixel).
  cv::VideoCapture capture((kFixtureDir / "talking_face.avi").string());
  const fs::path upright = dir_ / "upright", sideways = dir_ / "sideways";
  fs::create_directories(upright);
  fs::create_directories(sideways);
  cv::Mat bgr, turned;
  for (int i = 0; i < 40 && capture.read(bgr); ++i) {
    if (i % 8 != 0) continue;
    const std::string name = fmt::format("frame{:02}.png", i);
    cv::imwrite((upright / name).string(), bgr);
    cv::rotate(bgr, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
    cv::imwrite((sideways / name).string(), turned);
  }
  const fs::path expected = dir_ / "upright.csv", got = dir_ / "turned.csv", unturned = dir_ / "unturned.csv";
  for (const auto& [args, out] : {std::pair{upright.string(), expected}, std::pair{sideways.string() + " --rotate 90", got}}) {
    const ProcessRun run = run_process(args + " --include-landmarks --out " + out.string(), dir_);
    ASSERT_EQ(run.exit_code, 0) << args << ": " << run.stderr_text;
  }
  // Without the turn the face lies on its side, which is no face to the detector.
  const ProcessRun run = run_process(sideways.string() + " --out " + unturned.string(), dir_);
  EXPECT_EQ(run.exit_code, 65);
  EXPECT_NE(run.stderr_text.find("no face found in any of the 5 frames"), std::string::npos) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("--rotate 90 or 270"), std::string::npos) << "the error names the remedy\n"
                                                                           << run.stderr_text;
  const CsvTable want = read_csv_table(expected), have = read_csv_table(got);
  ASSERT_EQ(want.rows.size(), 5u);
  for (const double tracked : numeric_column(want, "tracked")) ASSERT_EQ(tracked, 1);
  EXPECT_EQ(have.header, want.header);
  EXPECT_EQ(have.rows, want.rows);
  const ProcessRun wrong = run_process(sideways.string() + " --rotate 45", dir_);
  EXPECT_NE(wrong.exit_code, 0);
  EXPECT_NE(wrong.stderr_text.find("--rotate"), std::string::npos) << wrong.stderr_text;
}

TEST_F(ProcessTest, AClipThatSaysHowToShowItIsProcessedAsShown) {
  // A phone held upright records its frames on their side and puts a display matrix in the
  // file; every player shows the clip upright, and so must lipdrive read it. The generated
  // clip losslessly: as it is, and turned a quarter anticlockwise with the matrix that turns
  // it back (the stream's rotate tag, written by a remux).
  const fs::path upright = dir_ / "upright.mov", coded = dir_ / "coded.mov", phone = dir_ / "phone.mov";
  const std::string clip = (kFixtureDir / "talking_face.avi").string();
  for (const std::string& command :
       {fmt::format("ffmpeg -v error -y -i {} -frames:v 8 -c:v ffv1 {}", clip, upright.string()),
        fmt::format("ffmpeg -v error -y -i {} -frames:v 8 -vf transpose=cclock -c:v ffv1 {}", clip, coded.string()),
        fmt::format("ffmpeg -v error -y -i {} -c copy -metadata:s:v:0 rotate=270 {}", coded.string(), phone.string())})
    ASSERT_EQ(test::run_command(command).exit_code, 0) << command;
  const fs::path expected = dir_ / "upright.csv", got = dir_ / "phone.csv";
  for (const auto& [input, out] : {std::pair{upright, expected}, std::pair{phone, got}}) {
    const ProcessRun run = run_process(input.string() + " --include-landmarks --out " + out.string(), dir_);
    ASSERT_EQ(run.exit_code, 0) << input << ": " << run.stderr_text;
  }
  CsvTable want = read_csv_table(expected), have = read_csv_table(got);
  ASSERT_EQ(want.rows.size(), 8u);
  for (const double tracked : numeric_column(want, "tracked")) ASSERT_EQ(tracked, 1);
  ASSERT_EQ(have.header, want.header);
  const auto source = std::ranges::find(want.header, "source") - want.header.begin();
  for (CsvTable* table : {&want, &have})
    for (auto& row : table->rows) row.erase(row.begin() + source);
  EXPECT_EQ(have.rows, want.rows) << "the same pixels, shown the same way";
}

TEST_F(ProcessTest, MissingInputFailsWithItsName) {
  const ProcessRun run = run_process((dir_ / "nothing.avi").string(), dir_);
  EXPECT_EQ(run.exit_code, 66);
  EXPECT_NE(run.stderr_text.find("nothing.avi"), std::string::npos) << run.stderr_text;
}

// A mistake on the command line is EX_USAGE (64) with CLI11's message; asking for help is not one.
TEST_F(ProcessTest, CommandLineMistakesExitWithUsage) {
  const ProcessRun unknown = run_process("--no-such-option x.avi", dir_);
  EXPECT_EQ(unknown.exit_code, 64) << unknown.stderr_text;
  EXPECT_NE(unknown.stderr_text.find("--no-such-option"), std::string::npos) << unknown.stderr_text;
  const ProcessRun missing = run_process("", dir_);
  EXPECT_EQ(missing.exit_code, 64) << missing.stderr_text;
  EXPECT_EQ(run_process("--help > /dev/null", dir_).exit_code, 0);
}

// A real-valued option's range refuses nan and infinities (CLI::Range let nan through: voice
// train ran with "look-ahead 0 ms", model render drew an empty picture, both exit 0).
TEST_F(ProcessTest, RealOptionsRefuseNanAndInfinity) {
  const std::string out = (dir_ / "out").string();
  for (const std::string& args :
       {"voice train --lookahead-ms nan --out " + out + ".lpv x.mpg", "model render --yaw nan --out " + out + ".png",
        "model render --yaw inf --out " + out + ".png", "calibrate --motion-seconds nan --out " + out + ".toml"}) {
    const test::CommandRun run = test::run_command(std::string(test::kLipdrive) + " " + args);
    EXPECT_EQ(run.exit_code, 64) << args << "\n" << run.output;
    EXPECT_NE(run.output.find("is not a number in"), std::string::npos) << args << "\n" << run.output;
  }
}

TEST_F(ProcessTest, APictureLargerThanACamerasIsADataErrorNamingItsSize) {
  const fs::path wide = dir_ / "wide.png";
  ASSERT_TRUE(cv::imwrite(wide.string(), cv::Mat(16, 9000, CV_8UC1, cv::Scalar(0))));
  const ProcessRun run = run_process(wide.string(), dir_);
  EXPECT_EQ(run.exit_code, 65) << run.stderr_text;
  EXPECT_NE(run.stderr_text.find(wide.string() + ": pictures of 9000×16 pixels; at most 8192 on a side"),
            std::string::npos)
      << run.stderr_text;
  // A header FFmpeg refuses itself (its return code reads "Device or resource busy"): the reason it logged.
  const fs::path huge = dir_ / "huge.y4m";
  std::ofstream(huge) << "YUV4MPEG2 W30000 H30000 F25:1 Ip A1:1 C420jpeg\nFRAME\n";
  const ProcessRun refused = run_process(huge.string(), dir_);
  EXPECT_EQ(refused.exit_code, 65) << refused.stderr_text;
  EXPECT_NE(refused.stderr_text.find(huge.string() + ": cannot open: IMGUTILS: Picture size 30000x30000 is invalid"),
            std::string::npos)
      << refused.stderr_text;
}

TEST_F(ProcessTest, TextFileIsNotAVideo) {
  const fs::path text = dir_ / "notes.txt";
  std::ofstream(text) << "not a video\n";
  const ProcessRun run = run_process(text.string(), dir_);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_LT(run.exit_code, 128) << "crashed: " << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("notes.txt"), std::string::npos) << run.stderr_text;
}

TEST_F(ProcessTest, UnreadableFolderFails) {
  const fs::path folder = dir_ / "locked";
  fs::create_directories(folder);
  fs::permissions(folder, fs::perms::none);
  if (::access(folder.c_str(), R_OK) == 0) GTEST_SKIP() << "running as root: chmod 000 does not lock the folder";
  const ProcessRun run = run_process(folder.string(), dir_);
  EXPECT_EQ(run.exit_code, 66);
  EXPECT_NE(run.stderr_text.find("locked"), std::string::npos) << run.stderr_text;
}

TEST_F(ProcessTest, AMissingSideRecordingOrVoiceModelLeavesTheOutputAsItWas) {
  const fs::path front = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(front);
  const fs::path out = dir_ / "keep.csv";
  constexpr const char* kEarlier = "an earlier table\n";
  std::ofstream(out) << kEarlier;
  for (const std::string option :
       {"--side " + (dir_ / "nosuch.avi").string(), "--voice " + (dir_ / "nosuch.lpv").string()}) {
    const ProcessRun run = run_process(fmt::format("{} {} --out {}", front.string(), option, out.string()), dir_);
    EXPECT_NE(run.exit_code, 0) << option;
    EXPECT_NE(run.stderr_text.find("nosuch"), std::string::npos) << run.stderr_text;
    std::ifstream in(out);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()), kEarlier) << option;
  }
}

// --out naming a file the command reads, by any spelling, is a mistake on the command line:
// the take, the configuration and the output all stay as they were (before, `process take.avi
// --out take.avi` replaced the take with its table and exited 0).
TEST_F(ProcessTest, AnOutThatIsAnInputIsRefusedAndBothStayAsTheyWere) {
  const fs::path source = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(source);
  const fs::path take = dir_ / "take.avi", link = dir_ / "link.avi", config = dir_ / "c.toml";
  fs::copy_file(source, take);
  fs::create_symlink(take, link);
  std::ofstream(config) << "[model]\n";
  const auto size = fs::file_size(take);
  for (const std::string& args :
       {fmt::format("{} --out {}", take.string(), take.string()),
        fmt::format("{} --out {}/./take.avi", take.string(), dir_.string()),
        fmt::format("{} --out {}", link.string(), take.string()),
        fmt::format("{} --config {} --out {}", take.string(), config.string(), config.string())}) {
    const ProcessRun run = run_process(args, dir_);
    EXPECT_EQ(run.exit_code, 64) << args << "\n" << run.stderr_text;
    EXPECT_NE(run.stderr_text.find("writing it would replace what the command reads"), std::string::npos) << args;
    EXPECT_EQ(fs::file_size(take), size) << args;
    EXPECT_EQ(file_text(config), "[model]\n") << args;
  }
}

// An input that gives no row at all (a recording without frames, a folder whose pictures
// cannot be read) leaves an earlier table as it was: the rows go to a file beside it that
// replaces it once they are all written.
TEST_F(ProcessTest, AnInputThatGivesNoRowLeavesTheOutputAsItWas) {
  const fs::path source = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(source);
  const fs::path empty = dir_ / "empty.avi", junk = dir_ / "junk";
  {
    cv::VideoWriter writer(empty.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25, cv::Size(64, 48), false);
    ASSERT_TRUE(writer.isOpened());
  }
  fs::create_directories(junk);
  std::ofstream(junk / "a.png") << "not a picture";
  const fs::path out = dir_ / "keep.csv";
  constexpr const char* kEarlier = "an earlier table\n";
  for (const fs::path& input : {empty, junk}) {
    std::ofstream(out) << kEarlier;
    const ProcessRun run = run_process(fmt::format("{} --out {}", input.string(), out.string()), dir_);
    EXPECT_EQ(run.exit_code, 65) << run.stderr_text;
    std::ifstream in(out);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()), kEarlier) << input;
  }
  // A finished run replaces it, and leaves no temporary file beside it.
  const ProcessRun run = run_process(fmt::format("{} --out {}", source.string(), out.string()), dir_);
  EXPECT_EQ(run.exit_code, 0) << run.stderr_text;
  EXPECT_EQ(read_csv_table(out).rows.size(), frame_count(source));
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
}

// A kill (or Ctrl-C) in the middle of a run ends it where it stands, by the signal, and takes
// its temporary file with it: the output as it was. A signal the process was told to ignore (the
// SIGINT of a shell's background job, nohup's SIGHUP) stays ignored: that run completes. The
// signal goes once the run has made its temporary file, while it works through a clip four
// times the fixture's length.
TEST_F(ProcessTest, AnInterruptedRunLeavesTheOutputAsItWas) {
  const fs::path source = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(source);
  const fs::path clip = dir_ / "long.avi";
  {
    cv::VideoCapture reader(source.string());
    std::vector<cv::Mat> frames;
    for (cv::Mat frame; reader.read(frame);) frames.push_back(frame.clone());
    ASSERT_FALSE(frames.empty());
    cv::VideoWriter writer(clip.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25, frames[0].size());
    ASSERT_TRUE(writer.isOpened());
    for (int pass = 0; pass < 4; ++pass)
      for (const cv::Mat& frame : frames) writer.write(frame);
  }
  const fs::path out = dir_ / "keep.csv";
  constexpr const char* kEarlier = "an earlier table\n";
  const auto run_and_signal = [&](const char* signal) {
    std::ofstream(out) << kEarlier;
    return test::run_command(
        fmt::format("cd {} && {{ {} process {} --out keep.csv & pid=$!; "
                    "until [ -e keep.csv.tmp$pid ] || ! kill -0 $pid 2>/dev/null; do sleep 0.001; done; "
                    "kill -{} $pid; wait $pid; echo exit $?; }}",
                    dir_.string(), test::kLipdrive, clip.string(), signal));
  };
  const auto output = [&] {
    std::ifstream in(out);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  };
  const test::CommandRun killed = run_and_signal("TERM");
  EXPECT_NE(killed.output.find(fmt::format("exit {}", 128 + SIGTERM)), std::string::npos) << killed.output;
  EXPECT_EQ(output(), kEarlier);
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
  const test::CommandRun ignored = run_and_signal("INT");
  EXPECT_NE(ignored.output.find("exit 0"), std::string::npos) << ignored.output;
  EXPECT_NE(output(), kEarlier) << "the run that ignored SIGINT replaced the output";
}

// An output that cannot be made is EX_CANTCREAT (73), one whose writing fails EX_IOERR (74),
// each naming the file (both were 1, the code of anything else that went wrong).
TEST_F(ProcessTest, AnOutputThatCannotBeMadeOrWrittenHasItsOwnExitCode) {
  const fs::path image = kFixtureDir / "astronaut.png";
  LIPDRIVE_REQUIRE_BUILT(image);
  const fs::path folder = dir_ / "folder.csv";
  fs::create_directory(folder);
  const ProcessRun made = run_process(fmt::format("{} --out {}", image.string(), folder.string()), dir_);
  EXPECT_EQ(made.exit_code, 73) << made.stderr_text;
  EXPECT_NE(made.stderr_text.find(folder.string() + ": cannot open for writing"), std::string::npos)
      << made.stderr_text;
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full here to fail a write";
  const ProcessRun full = run_process(fmt::format("{} --out /dev/full", image.string()), dir_);
  EXPECT_EQ(full.exit_code, 74) << full.stderr_text;
  EXPECT_NE(full.stderr_text.find("/dev/full: write failed"), std::string::npos) << full.stderr_text;
}

// --out through a symbolic link replaces the file it points to and keeps the link; --out to
// something that is not a file (/dev/stdout, a FIFO) is written straight through.
TEST_F(ProcessTest, AnOutputThroughALinkOrToAStreamIsWrittenWhereItPoints) {
  const fs::path image = kFixtureDir / "astronaut.png";
  LIPDRIVE_REQUIRE_BUILT(image);
  const fs::path target = dir_ / "v1.csv", link = dir_ / "latest.csv";
  std::ofstream(target) << "an earlier table\n";
  fs::create_symlink(target, link);
  ProcessRun run = run_process(fmt::format("{} --out {}", image.string(), link.string()), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  EXPECT_TRUE(fs::is_symlink(link));
  EXPECT_EQ(read_csv_table(target).rows.size(), 1u);

  const fs::path piped = dir_ / "piped.csv";
  run = run_process(fmt::format("{} --out /dev/stdout > {}", image.string(), piped.string()), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  EXPECT_EQ(read_csv_table(piped).rows.size(), 1u);
  for (const auto& entry : fs::directory_iterator(dir_))
    EXPECT_EQ(entry.path().string().find(".tmp"), std::string::npos) << entry.path();
}

TEST_F(ProcessTest, VideoWithoutAFaceWritesUntrackedRowsAndFails) {
  const fs::path noise = dir_ / "noise.avi";
  {
    cv::VideoWriter writer(noise.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25, cv::Size(320, 240));
    ASSERT_TRUE(writer.isOpened());
    cv::Mat frame(240, 320, CV_8UC3);
    for (int i = 0; i < 12; ++i) {
      cv::randu(frame, cv::Scalar::all(0), cv::Scalar::all(255));
      writer.write(frame);
    }
  }
  const fs::path out = dir_ / "noise.csv";
  const ProcessRun run = run_process(noise.string() + " --out " + out.string(), dir_);
  EXPECT_NE(run.exit_code, 0);
  EXPECT_LT(run.exit_code, 128) << "crashed: " << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("no face"), std::string::npos) << run.stderr_text;
  const CsvTable table = read_csv_table(out);
  EXPECT_EQ(table.rows.size(), 12u);
  const auto tracked = numeric_column(table, "tracked");
  EXPECT_TRUE(std::all_of(tracked.begin(), tracked.end(), [](double t) { return t == 0; }));
  const auto height = numeric_column(table, "height_fit");
  EXPECT_TRUE(std::all_of(height.begin(), height.end(), [](double h) { return std::isnan(h); }));
}

// A take can come through a pipe (another program decoding or receiving it): read once, every
// frame becomes a row, the identity gathered as live (the pass that fits it first needs a file
// it can read twice).
TEST_F(ProcessTest, ATakeThroughAPipeIsReadOnce) {
  const fs::path source = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(source);
  const fs::path pipe = dir_ / "take.fifo", out = dir_ / "pipe.csv";
  ASSERT_EQ(::mkfifo(pipe.c_str(), 0600), 0) << std::strerror(errno);
  ASSERT_EQ(std::system(fmt::format("cat '{}' > '{}' &", source.string(), pipe.string()).c_str()), 0);
  const ProcessRun run = run_process(pipe.string() + " --out " + out.string(), dir_);
  ::close(::open(pipe.c_str(), O_RDONLY | O_NONBLOCK));  // whatever happened, the writer is not left waiting
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  EXPECT_EQ(read_csv_table(out).rows.size(), frame_count(source));
  EXPECT_NE(run.stderr_text.find("identity: fitted from the first 20 tracked frames"), std::string::npos)
      << run.stderr_text;
}

// The talking face retimed to 25, then 50, then 25 frames per second (the file states 25): each
// row's time_s is its frame's own time, not its frame number over the stated rate, and the
// frame numbers stay unique and increasing.
TEST_F(ProcessTest, AVariableRateClipsRowsCarryTheirFramesOwnTimes) {
  const fs::path source = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(source);
  const int frames = static_cast<int>(frame_count(source));
  const fs::path clip = dir_ / "variable.mkv", out = dir_ / "variable.csv";
  const test::CommandRun made = test::variable_rate_clip(source, frames, clip);
  ASSERT_EQ(made.exit_code, 0) << made.output;
  const ProcessRun run = run_process(clip.string() + " --out " + out.string(), dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  const CsvTable table = read_csv_table(out);
  const std::vector<double> times = test::variable_rate_times(frames), time_s = numeric_column(table, "time_s"),
                            frame = numeric_column(table, "frame");
  ASSERT_EQ(time_s.size(), times.size());
  for (std::size_t i = 0; i < times.size(); ++i) {
    EXPECT_NEAR(time_s[i], times[i], 1e-6) << "row " << i;
    if (i > 0) EXPECT_GT(frame[i], frame[i - 1]) << "row " << i;
  }
}

// A 29.97 fps recording whose container keeps times to the millisecond (Matroska): frame 1 at
// 33 ms lies before the 33.37 ms at which timecode frame 1 starts. Every row's timecode is its
// own, one after the other: none repeated, none skipped.
TEST_F(ProcessTest, TheTimecodeColumnCountsTheRecordingsFramesOneByOne) {
  const fs::path source = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(source);
  const fs::path clip = dir_ / "ntsc.mkv", out = dir_ / "ntsc.csv";
  ASSERT_EQ(test::run_command(fmt::format("ffmpeg -v error -y -r 30000/1001 -i {} -frames:v 60 -c:v mjpeg -q:v 3 {}",
                                          source.string(), clip.string()))
                .exit_code,
            0);
  const ProcessRun run =
      run_process(fmt::format("{} --timecode 01:00:00:00 --timecode-fps 29.97 --out {}", clip.string(), out.string()),
                  dir_);
  ASSERT_EQ(run.exit_code, 0) << run.stderr_text;
  const CsvTable table = read_csv_table(out);
  const auto column = std::find(table.header.begin(), table.header.end(), "timecode");
  ASSERT_NE(column, table.header.end());
  ASSERT_EQ(table.rows.size(), 60u);
  for (std::size_t row = 0; row < table.rows.size(); ++row) {
    const std::string& timecode = table.rows[row][static_cast<std::size_t>(column - table.header.begin())];
    // No frame is dropped from the count in the first two seconds of the hour.
    EXPECT_EQ(timecode, fmt::format("01:00:{:02d};{:02d}", row / 30, row % 30)) << "row " << row;
  }
}

TEST_F(ProcessTest, DamagedVideoKeepsTheRowsBeforeTheDamage) {
  const fs::path source = kFixtureDir / "talking_face.avi";
  LIPDRIVE_REQUIRE_BUILT(source);
  const fs::path damaged = dir_ / "damaged.avi";
  fs::copy_file(source, damaged);
  fs::resize_file(damaged, fs::file_size(source) / 2);
  const fs::path out = dir_ / "damaged.csv";
  const ProcessRun run = run_process(damaged.string() + " --out " + out.string(), dir_);
  EXPECT_NE(run.exit_code, 0) << run.stderr_text;
  EXPECT_LT(run.exit_code, 128) << "crashed: " << run.stderr_text;
  EXPECT_NE(run.stderr_text.find("damaged"), std::string::npos) << run.stderr_text;
  const CsvTable table = read_csv_table(out);
  EXPECT_GT(table.rows.size(), 5u);
  EXPECT_LT(table.rows.size(), frame_count(source));
  const auto tracked = numeric_column(table, "tracked");
  EXPECT_EQ(tracked.front(), 1);
  // The frames lost are those the AVI states past the rows, not the one damage that ended it.
  EXPECT_NE(
      run.stderr_text.find(fmt::format("{} frames could not be decoded (named above); the other {} were processed",
                                       frame_count(source) - table.rows.size(), table.rows.size())),
      std::string::npos)
      << run.stderr_text;
}

}  // namespace
}  // namespace lipdrive
