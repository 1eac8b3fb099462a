// The CSV reader, GRID alignments, and the `lipdrive eval` and `lipdrive plot`
// commands run as a user runs them (the built binary on small files).
#include "build_paths.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "firmware_app/tables/grid_align.hpp"
#include "firmware_app/tables/measures_csv.hpp"
#include "fixture_paths.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

/// The CommandError `action` throws; a test failure saying `accepted` when it throws none.
CommandError error_of(const std::function<void()>& action, const std::string& accepted) {
  try {
    action();
  } catch (const CommandError& e) {
    return e;
  }
  ADD_FAILURE() << accepted;
  return CommandError("");
}

struct RunResult {
  int exit_code = -1;
  std::string out;  // stdout
  std::string err;  // stderr
};

std::string read_text(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A worked example of the closure metric at GRID's 25 fps: silence 0-1, "bin" 2-3 (the lips
// meet at frame 3), "one" 4-6, "please" 7-8 (within 2 frames of it nothing below 0.3 of the
// range), final silence 9-16, scored from frame 12.
constexpr std::array kWorkedOpen = {0.1, 0.1, 0.5, 0.0, 0.8,  1.0, 0.9, 0.6, 0.55,
                                    0.3, 0.3, 0.1, 0.1, 0.12, 0.1, 0.1, 0.1};
constexpr const char* kWorkedAlign = "0 2000 sil\n2000 4000 bin\n4000 7000 one\n7000 9000 please\n9000 17000 sil\n";

class EvalPlotTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / ("lipdrive_" + std::string(test->name()) + "_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path path = dir_ / name;
    std::ofstream(path) << text;
    return path;
  }

  /// Runs the lipdrive binary with the given arguments (each single-quoted), after `prefix`.
  RunResult run(const std::vector<std::string>& args, const std::string& prefix = "") const {
    std::string command = prefix + test::kLipdrive;
    for (const auto& arg : args) command += " '" + arg + "'";
    const fs::path err_path = dir_ / "stderr.txt";
    command += " 2>'" + err_path.string() + "'";
    RunResult result;
    FILE* pipe = ::popen(command.c_str(), "r");
    if (pipe == nullptr) return result;
    char buffer[4096];
    for (std::size_t n; (n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0;) result.out.append(buffer, n);
    const int status = ::pclose(pipe);
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    result.err = read_text(err_path);
    return result;
  }

  /// `lipdrive eval --json` of `csv` (an `open` column) against the worked example's transcript:
  /// the closure report of that column.
  nlohmann::json closure_of(const std::string& csv) const {
    const RunResult result = run({"eval", "--pred", write("pred.csv", csv), "--align",
                                  write("take.align", kWorkedAlign), "--columns", "open", "--json"});
    EXPECT_EQ(result.exit_code, 0) << result.err;
    return result.exit_code == 0 ? nlohmann::json::parse(result.out).at("closure")[0] : nlohmann::json::object();
  }

  fs::path dir_;
};

// Ground truth as the fixture generator writes it.
constexpr const char* kTruthCsv =
    "frame,time_s,width_2d,height_2d\n"
    "0,0.00,10,1\n"
    "1,0.04,12,3\n"
    "2,0.08,14,5\n"
    "3,0.12,16,7\n"
    "4,0.16,18,9\n";

// `lipdrive process` output: frame 0 missing, frame 3 untracked (empty measures),
// frame 5 not in the truth, a quoted source path. width_2d = truth + 1;
// height_2d = 7.5 - 0.5 × truth (3, 5, 9 → 6, 5, 3 on the tracked common frames).
constexpr const char* kPredCsv =
    "frame,time_s,source,tracked,quality,width_2d,height_2d,width_fit,height_fit,width_3d,"
    "height_3d,protrusion_3d\n"
    "1,0.04,\"/takes/take 1.mp4\",1,0.9,13,6,1,1,1,1,1\n"
    "2,0.08,\"/takes/take 1.mp4\",1,0.9,15,5,1,1,1,1,1\n"
    "3,0.12,\"/takes/take 1.mp4\",0,0.1,,,,,,,\n"
    "4,0.16,\"/takes/take 1.mp4\",1,0.9,19,3,1,1,1,1,1\n"
    "5,0.20,\"/takes/take 1.mp4\",1,0.9,20,2,1,1,1,1,1\n";

const nlohmann::json& column_result(const nlohmann::json& report, const std::string& name) {
  for (const auto& column : report.at("columns")) {
    if (column.at("column") == name) return column;
  }
  throw std::runtime_error("no result for column " + name);
}

TEST_F(EvalPlotTest, EvalJsonMatchesHandComputedMetrics) {
  const auto truth = write("truth.csv", kTruthCsv);
  const auto pred = write("pred.csv", kPredCsv);
  const RunResult result = run({"eval", "--truth", truth, "--pred", pred, "--json"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const auto report = nlohmann::json::parse(result.out);

  EXPECT_EQ(report.at("frames_matched"), 4);   // frames 1-4
  ASSERT_EQ(report.at("columns").size(), 2u);  // the measures both files have

  const auto& width = column_result(report, "width_2d");
  EXPECT_EQ(width.at("n"), 3);  // frame 3 is untracked
  EXPECT_NEAR(width.at("rmse_scaled").get<double>(), 0, 1e-12);
  EXPECT_NEAR(width.at("mae").get<double>(), 1, 1e-12);
  EXPECT_NEAR(width.at("max_abs").get<double>(), 1, 1e-12);
  EXPECT_NEAR(width.at("pearson_r").get<double>(), 1, 1e-12);
  EXPECT_NEAR(width.at("std_ratio").get<double>(), 1, 1e-12);

  // Truth 3, 5, 9 scales to 0, 1/3, 1; output 6, 5, 3 to 1, 2/3, 0.
  const auto& height = column_result(report, "height_2d");
  EXPECT_EQ(height.at("n"), 3);
  EXPECT_NEAR(height.at("rmse_scaled").get<double>(), std::sqrt((1 + 1.0 / 9 + 1) / 3), 1e-12);
  EXPECT_NEAR(height.at("mae").get<double>(), (3 + 0 + 6) / 3.0, 1e-12);
  EXPECT_NEAR(height.at("max_abs").get<double>(), 6, 1e-12);
  EXPECT_NEAR(height.at("pearson_r").get<double>(), -1, 1e-12);
  EXPECT_NEAR(height.at("std_ratio").get<double>(), 0.5, 1e-12);
}

TEST_F(EvalPlotTest, EvalWithAlignmentScoresOnlySpeechFrames) {
  const auto truth = write("truth.csv", kTruthCsv);
  const auto pred = write("pred.csv", kPredCsv);
  // Speech spans frames 2 and 3 only; frame 3 is untracked.
  const auto align = write("take.align", "0 2000 sil\n2000 4000 bin\n4000 6000 sp\n");
  const RunResult result =
      run({"eval", "--truth", truth, "--pred", pred, "--align", align, "--columns", "width_2d", "--json"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const auto report = nlohmann::json::parse(result.out);
  EXPECT_EQ(report.at("frames_matched"), 2);
  ASSERT_EQ(report.at("columns").size(), 1u);
  const auto& width = column_result(report, "width_2d");
  EXPECT_EQ(width.at("n"), 1);
  EXPECT_NEAR(width.at("mae").get<double>(), 1, 1e-12);
  EXPECT_TRUE(width.at("pearson_r").is_null());  // one pair: no correlation
}

TEST_F(EvalPlotTest, SpeechFramesAreTheWordsMergedIntoRanges) {
  // At 25 fps: words on frames 2-3, 3-5 (overlapping), 6 (touching), silence on 7-9, 10-11.
  const std::vector<AlignedWord> words{
      {2000, 4000, "bin"}, {3000, 6000, "blue"}, {6000, 7000, "at"}, {7000, 10000, "sp"}, {10000, 12000, "f"}};
  const auto speech = speech_frames(words, kGridFramesPerSecond);
  ASSERT_EQ(speech.size(), 2u);
  EXPECT_EQ(speech[0].first, 2);
  EXPECT_EQ(speech[0].last, 6);
  EXPECT_EQ(speech[1].first, 10);
  EXPECT_EQ(speech[1].last, 11);
  for (int frame : {1, 7, 9, 12}) EXPECT_FALSE(contains(speech, frame)) << frame;
  for (int frame : {2, 4, 6, 10, 11}) EXPECT_TRUE(contains(speech, frame)) << frame;
}

// A bilabial word none of whose frames (widened by two each side) was tracked says so (it read "minimum nan"); a folder
// given as a table is named as one (it read "error reading").
TEST_F(EvalPlotTest, AnUntrackedWordAndAFolderForATableAreNamedSo) {
  std::string csv = "frame,tracked,open\n";
  for (std::size_t f = 0; f < kWorkedOpen.size(); ++f)
    csv += f < 6 ? fmt::format("{},0,\n", f) : fmt::format("{},1,{}\n", f, kWorkedOpen[f]);
  const auto pred = write("pred.csv", csv);
  const auto align = write("take.align", kWorkedAlign);
  const RunResult table = run({"eval", "--pred", pred, "--align", align, "--columns", "open"});
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_THAT(table.out, HasSubstr("\"bin\" (frames 2..3) not closed: no frame of it tracked"));
  const fs::path folder = dir_ / "folder.csv";
  fs::create_directory(folder);
  const RunResult read = run({"eval", "--pred", folder.string(), "--align", align});
  EXPECT_EQ(read.exit_code, 66);
  EXPECT_THAT(read.err, HasSubstr(folder.string() + ": a folder, not a CSV table"));
}

TEST_F(EvalPlotTest, EvalWithAlignmentOfLongWordsAtAHighFrameRateIsQuick) {
  // Rows 1 ms apart: 1000 frames/s, and an hour of words, 200 of 18 s each: 3.6 million frames,
  // the last row at the end. Every frame of every word was enumerated into a set (200
  // overlapping hour-long words: 55 s, 390 MB; words must now follow one another).
  const auto fast = write("fast.csv", "frame,time_s,width_2d\n0,0,1\n1,0.001,2\n3599999,3599.999,3\n");
  std::string words;
  for (long i = 0; i < 200; ++i) words += fmt::format("{} {} bin\n", i * 450'000, (i + 1) * 450'000);
  const auto align = write("long.align", words);
  const RunResult result = run({"eval", "--truth", fast, "--pred", fast, "--align", align, "--json"}, "timeout 60 ");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const auto report = nlohmann::json::parse(result.out);
  EXPECT_EQ(report.at("frames_matched"), 3);
  EXPECT_EQ(report.at("closure").at(0).at("bilabial_words"), 200);
}

TEST_F(EvalPlotTest, EvalWithAlignmentAloneReportsTheClosureMetric) {
  std::string csv = "frame,tracked,open\n";
  for (std::size_t f = 0; f < kWorkedOpen.size(); ++f) csv += fmt::format("{},1,{}\n", f, kWorkedOpen[f]);
  const auto pred = write("pred.csv", csv);
  const auto align = write("take.align", kWorkedAlign);
  const RunResult result = run({"eval", "--pred", pred, "--align", align, "--columns", "open", "--json"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const auto report = nlohmann::json::parse(result.out);
  EXPECT_TRUE(report.at("truth").is_null());
  ASSERT_EQ(report.at("closure").size(), 1u);
  const auto& closure = report.at("closure")[0];
  EXPECT_EQ(closure.at("column"), "open");
  EXPECT_EQ(closure.at("bilabial_words"), 2);
  EXPECT_EQ(closure.at("closures_seen"), 1);  // "bin" closes, "please" does not
  // Scaled by the maximum 1.0: speech frames 2..8 are 0.5 0 0.8 1 0.9 0.6 0.55; 90th percentile
  // by nearest rank (rank 7 of 7) = 1.
  EXPECT_NEAR(closure.at("opening").get<double>(), 1.0, 1e-9);
  // Final silence from frame 12: 0.1 0.12 0.1 0.1 0.1 -> median 0.1, jitter (0.02+0.02)/4.
  EXPECT_NEAR(closure.at("silence_median").get<double>(), 0.1, 1e-9);
  EXPECT_NEAR(closure.at("silence_jitter").get<double>(), 0.01, 1e-9);
  ASSERT_EQ(closure.at("words").size(), 2u);
  EXPECT_EQ(closure.at("words")[0].at("word"), "bin");
  EXPECT_TRUE(closure.at("words")[0].at("closed").get<bool>());

  const RunResult table = run({"eval", "--pred", pred, "--align", align, "--columns", "open"});
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_THAT(table.out, HasSubstr("closures"));
  EXPECT_THAT(table.out, HasSubstr("1/2"));

  const RunResult neither = run({"eval", "--pred", pred});
  EXPECT_NE(neither.exit_code, 0);
  EXPECT_THAT(neither.err, HasSubstr("--truth"));
}

TEST_F(EvalPlotTest, EvalPlacesTheWordsOnTheFramesOfARecordingAtAnyRate) {
  // The worked example recorded at 50 frames/s (each frame twice): the words fall on the
  // frames of their times, and the widening and the silence's delay are the same times, so the
  // figures are the same.
  std::string csv = "frame,time_s,tracked,open\n";
  for (std::size_t f = 0; f < 2 * kWorkedOpen.size(); ++f)
    csv += fmt::format("{},{:.4f},1,{}\n", f, f / 50.0, kWorkedOpen[f / 2]);
  const nlohmann::json closure = closure_of(csv);
  ASSERT_FALSE(closure.empty());
  EXPECT_EQ(closure.at("closures_seen"), 1);  // "bin" closes, "please" does not
  EXPECT_NEAR(closure.at("opening").get<double>(), 1.0, 1e-9);
  // Final silence from frame 18 + 6: 0.1 0.1 0.12 0.12 0.1 0.1 0.1 0.1 0.1 0.1.
  EXPECT_NEAR(closure.at("silence_median").get<double>(), 0.1, 1e-9);
  EXPECT_NEAR(closure.at("silence_jitter").get<double>(), 0.04 / 9, 1e-9);
  ASSERT_EQ(closure.at("words").size(), 2u);
  EXPECT_EQ(closure.at("words")[1].at("first"), 14);  // "please" from 7000 / 25000 s

  const RunResult table = run(
      {"eval", "--pred", (dir_ / "pred.csv").string(), "--align", (dir_ / "take.align").string(), "--columns", "open"});
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_THAT(table.out, HasSubstr("at 50 frames/s"));
}

TEST_F(EvalPlotTest, EvalPlacesTheWordsFromTheEarliestRowWhateverItsFrameNumber) {
  // The worked example as a take numbers it: frames from its capture sequence number, which
  // may be near the int limit the frame column allows.
  for (const int first : {5000, 900000000}) {
    std::string csv = "frame,time_s,tracked,open\n";
    for (std::size_t f = 0; f < kWorkedOpen.size(); ++f)
      csv += fmt::format("{},{:.4f},1,{}\n", first + static_cast<int>(f), 100 + f / 25.0, kWorkedOpen[f]);
    const nlohmann::json closure = closure_of(csv);
    ASSERT_FALSE(closure.empty());
    ASSERT_EQ(closure.at("closures_seen"), 1) << first;
    EXPECT_EQ(closure.at("bilabial_words"), 2) << first;
    EXPECT_NEAR(closure.at("opening").get<double>(), 1.0, 1e-9) << first;
    EXPECT_NEAR(closure.at("silence_median").get<double>(), 0.1, 1e-9) << first;
    EXPECT_NEAR(closure.at("silence_jitter").get<double>(), 0.01, 1e-9) << first;
    EXPECT_EQ(closure.at("words")[1].at("first"), first + 7);  // "please", on the CSV's frame numbers
  }
}

TEST_F(EvalPlotTest, EvalOfARowFarPastTheWordsCostsNoMemoryAndScalesAsAnyOther) {
  // The worked example and one row more past its words, its value the highest: at frame 17 (held in
  // the series, which reaches a closure window's widening past the last word) and at frame 900,000,000 (a table without
  // time_s, so its rate is not checked) the figures are the same; the frames between are not held
  // one by one (a row at 999,999,999 took 15.7 GB and 55 s).
  std::string csv = "frame,tracked,open\n";
  for (std::size_t f = 0; f < kWorkedOpen.size(); ++f) csv += fmt::format("{},1,{}\n", f, kWorkedOpen[f]);
  const nlohmann::json near = closure_of(csv + "17,1,2.0\n"), far = closure_of(csv + "900000000,1,2.0\n");
  ASSERT_FALSE(near.empty());
  EXPECT_EQ(far, near);
  // Scaled by the new maximum 2.0: the opening halves.
  EXPECT_NEAR(near.at("opening").get<double>(), 0.5, 1e-9);
  EXPECT_NEAR(near.at("silence_median").get<double>(), 0.05, 1e-9);
  EXPECT_EQ(near.at("closures_seen"), 2);  // "please": its window's lowest, 0.3, scales to 0.15
}

TEST_F(EvalPlotTest, EvalReportsWordsPastTheRowsAsOutsideNotAsMissedClosures) {
  // The worked example cut after frame 5: "please" (frames 7-8) and the final silence are
  // not in the recording.
  std::string csv = "frame,tracked,open\n";
  for (std::size_t f = 0; f < 6; ++f) csv += fmt::format("{},1,{}\n", f, kWorkedOpen[f]);
  const nlohmann::json closure = closure_of(csv);
  ASSERT_FALSE(closure.empty());
  EXPECT_EQ(closure.at("bilabial_words"), 1);
  EXPECT_EQ(closure.at("closures_seen"), 1);
  ASSERT_EQ(closure.at("words").size(), 2u);
  EXPECT_FALSE(closure.at("words")[0].at("outside").get<bool>());
  EXPECT_TRUE(closure.at("words")[1].at("outside").get<bool>());
  EXPECT_FALSE(closure.at("words")[1].at("closed").get<bool>());
  EXPECT_TRUE(closure.at("silence_median").is_null());

  const RunResult table = run({"eval", "--pred", (dir_ / "pred.csv").string(), "--align",
                               (dir_ / "take.align").string(), "--columns", "open"});
  ASSERT_EQ(table.exit_code, 0) << table.err;
  EXPECT_THAT(table.out, HasSubstr("1/1"));
  EXPECT_THAT(table.out, HasSubstr("\"please\" (frames 7..8) outside the rows: not scored"));
}

TEST_F(EvalPlotTest, EvalComparesTwoProcessOutputsAsATable) {
  const auto a = write("a.csv", kPredCsv);
  const auto b = write("b.csv", kPredCsv);
  const RunResult result = run({"eval", "--truth", a, "--pred", b});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_THAT(result.out, HasSubstr("rmse_scaled"));
  // All seven measures of the process output, each on its 4 tracked frames.
  for (const char* column :
       {"width_2d", "height_2d", "width_fit", "height_fit", "width_3d", "height_3d", "protrusion_3d"}) {
    EXPECT_THAT(result.out, HasSubstr(column));
  }
  EXPECT_THAT(result.out, HasSubstr("5 frames matched"));
}

TEST_F(EvalPlotTest, EvalErrorsNameTheProblem) {
  const auto truth = write("truth.csv", kTruthCsv);
  const auto pred = write("pred.csv", kPredCsv);

  const RunResult missing_file = run({"eval", "--truth", (dir_ / "nope.csv").string(), "--pred", pred});
  EXPECT_EQ(missing_file.exit_code, 66);
  EXPECT_THAT(missing_file.err, HasSubstr("nope.csv"));

  const RunResult missing_column = run({"eval", "--truth", truth, "--pred", pred, "--columns", "lip_gloss"});
  EXPECT_EQ(missing_column.exit_code, 65);
  EXPECT_THAT(missing_column.err, HasSubstr("lip_gloss"));

  const auto later = write("later.csv", "frame,width_2d,height_2d\n10,1,1\n11,2,2\n");
  const RunResult disjoint = run({"eval", "--truth", truth, "--pred", later});
  EXPECT_EQ(disjoint.exit_code, 65);
  EXPECT_THAT(disjoint.err, HasSubstr("no frames in common"));

  const auto ragged = write("ragged.csv", "frame,width_2d\n0,1\n1,2,3\n");
  const RunResult malformed = run({"eval", "--truth", truth, "--pred", ragged});
  EXPECT_EQ(malformed.exit_code, 65);
  EXPECT_THAT(malformed.err, HasSubstr(ragged.string() + ":3"));

  // Frames a microsecond apart: no frame rate the words could be placed at.
  const auto hurried = write("hurried.csv", "frame,time_s,tracked,open\n0,0,1,0.1\n1000,0.001,1,0.2\n");
  const auto align = write("take.align", "0 2000 sil\n2000 4000 bin\n");
  const RunResult rate = run({"eval", "--pred", hurried, "--align", align});
  EXPECT_EQ(rate.exit_code, 65);
  EXPECT_THAT(rate.err, HasSubstr(hurried.string() + ": its frame and time_s columns give 1e+06 frames per second"));

  // A clock that stands still, and one that runs back: no rate either (both read as 25 frames/s).
  for (const auto& [first, last] : {std::pair{"0", "0"}, std::pair{"0.08", "0.04"}}) {
    const auto still = write("still.csv", fmt::format("frame,time_s,tracked,open\n0,{},1,0.1\n1,{},1,0.2\n", first, last));
    const RunResult stopped = run({"eval", "--pred", still, "--align", align});
    EXPECT_EQ(stopped.exit_code, 65) << last;
    EXPECT_THAT(stopped.err, HasSubstr(still.string() + ": time_s of the last row")) << last;
  }

  // Frames at 25, then 50, then 25 frames/s: no one rate places the words on them.
  std::string varying = "frame,time_s,tracked,open\n";
  double t = 0;
  for (int f = 0; f < 60; ++f, t += (f >= 20 && f < 40) ? 0.02 : 0.04)
    varying += fmt::format("{},{:.4f},1,0.1\n", f, t);
  const auto vfr = write("vfr.csv", varying);
  const RunResult unsteady = run({"eval", "--pred", vfr, "--align", align});
  EXPECT_EQ(unsteady.exit_code, 65);
  EXPECT_THAT(unsteady.err, HasSubstr(vfr.string() + ": frame 5 is at 0.2000 s"));  // the first one off
  EXPECT_THAT(unsteady.err, HasSubstr("not at one rate"));
}

TEST_F(EvalPlotTest, CsvReaderHandlesQuotesAndEmptyFields) {
  const auto path = write("quoted.csv",
                          "frame,source,width_2d\r\n"
                          "0,\"a, b \"\"c\"\"\",1.5\r\n"
                          "\n"
                          "1,plain,\r\n");
  const CsvTable table = read_csv_table(path);
  ASSERT_EQ(table.rows.size(), 2u);
  EXPECT_EQ(table.rows[0][column_index(table, "source")], "a, b \"c\"");
  EXPECT_EQ(table.line_numbers[1], 4);
  const auto width = numeric_column(table, "width_2d");
  EXPECT_DOUBLE_EQ(width[0], 1.5);
  EXPECT_TRUE(std::isnan(width[1]));
}

TEST_F(EvalPlotTest, CsvReaderErrorsNameFileLineAndColumn) {
  const auto ragged = write("ragged.csv", "frame,width_2d\n0,1\n1\n");
  const CommandError short_row = error_of([&] { read_csv_table(ragged); }, "a row with too few fields was accepted");
  EXPECT_THAT(short_row.what(), HasSubstr(ragged.string() + ":3"));
  EXPECT_EQ(short_row.exit_code(), kExitDataError);

  const CsvTable table = read_csv_table(write("words.csv", "frame,width_2d\n0,1\n1,wide\n"));
  const CommandError word = error_of([&] { numeric_column(table, "width_2d"); }, "a non-number was accepted");
  EXPECT_THAT(word.what(), HasSubstr("words.csv:3"));
  EXPECT_THAT(word.what(), HasSubstr("width_2d"));
  EXPECT_THAT(word.what(), HasSubstr("wide"));
  EXPECT_THROW(column_index(table, "height_2d"), CommandError);

  const auto twice = write("twice.csv", "# take\nframe,width_2d,height_2d,width_2d\n0,1,2,3\n");
  const CommandError duplicate = error_of([&] { read_csv_table(twice); }, "a column named twice was accepted");
  EXPECT_THAT(duplicate.what(), HasSubstr(twice.string() + ":2: duplicate column 'width_2d'"));
  EXPECT_EQ(duplicate.exit_code(), kExitDataError);
}

TEST_F(EvalPlotTest, EvalRefusesANonFiniteValueNamingFileLineAndColumn) {
  // It was read as a value: "rmse_scaled -nan" and "n 2" against "3 frames matched", without a
  // word; a nan was taken for a missing value (which is an empty field).
  for (const char* value : {"inf", "-inf", "nan"}) {
    const auto pred = write("pred.csv", fmt::format("frame,time_s,width_2d\n0,0,1\n1,0.04,{}\n2,0.08,3\n", value));
    const auto truth = write("truth.csv", "frame,time_s,width_2d\n0,0,1\n1,0.04,2\n2,0.08,3\n");
    const RunResult result = run({"eval", "--truth", truth, "--pred", pred});
    EXPECT_EQ(result.exit_code, 65) << value;
    EXPECT_THAT(result.err,
                HasSubstr(fmt::format("{}:3: column 'width_2d': '{}' is not a finite number", pred.string(), value)));
  }
}

// A measure that is not finite is written as a missing value, an empty field, which the readers
// take as missing; it was written as "nan", which they now refuse.
TEST_F(EvalPlotTest, AMeasureThatIsNotFiniteIsWrittenAsAMissingValue) {
  MouthMeasures measures;
  measures.width_2d = 1.5;
  measures.height_fit = std::nan("");
  measures.open = std::numeric_limits<double>::infinity();
  const std::array<float, kNumVisemes> visemes{};
  const std::array<float, kNumArkit> arkit{};
  fmt::memory_buffer row;
  append_measures_csv_row(row, {.frame = 0, .time_s = 0, .source = "take"}, &measures, visemes, arkit, nullptr);
  const auto table = read_csv_table(write("rows.csv", measures_csv_header(false) + "\n" + fmt::to_string(row) + "\n"));
  EXPECT_EQ(numeric_column(table, "width_2d")[0], 1.5);
  EXPECT_TRUE(std::isnan(numeric_column(table, "height_fit")[0]));
  EXPECT_TRUE(std::isnan(numeric_column(table, "open")[0]));
  EXPECT_EQ(numeric_column(table, "seal")[0], 0);
}

TEST_F(EvalPlotTest, EvalOfATableWithManyColumnsIsQuick) {
  // Each column name was compared with every other: 100,000 columns took over a minute.
  constexpr int kColumns = 100000;
  std::string header = "frame", row = "0";
  for (int i = 0; i < kColumns; ++i) {
    header += fmt::format(",c{}", i);
    row += ",1";
  }
  const auto wide = write("wide.csv", header + "\n" + row + "\n");
  const RunResult result = run({"eval", "--truth", wide, "--pred", wide}, "timeout 60 ");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_THAT(result.out, HasSubstr("1 frames matched"));
  EXPECT_THAT(result.out, HasSubstr(fmt::format("\nc{} ", kColumns - 1)));
}

TEST_F(EvalPlotTest, GridAlignmentOfSharedFixture) {
  const fs::path align = test::shared_fixtures() / "grid" / "bbaf2n.align";
  LIPDRIVE_SKIP_WITHOUT_SHARED(align);
  const auto words = read_grid_align(align);
  ASSERT_EQ(words.size(), 8u);  // sil bin blue at f two now sil

  // "bin" is 23750-29500: frame 23 spans 23000-24000 and overlaps it, frame 29
  // spans 29000-30000 and holds its end, frame 30 starts at its end.
  const auto bin = word_frame_range(words, "bin", kGridFramesPerSecond);
  ASSERT_TRUE(bin.has_value());
  EXPECT_EQ(bin->first, 23);
  EXPECT_EQ(bin->last, 29);
  EXPECT_FALSE(word_frame_range(words, "lay", kGridFramesPerSecond).has_value());

  // Speech runs from "bin" to "now" (47250-53000: frames 47-52) without a pause.
  const auto speech = speech_frames(words, kGridFramesPerSecond);
  ASSERT_EQ(speech.size(), 1u);
  EXPECT_EQ(speech[0].first, 23);
  EXPECT_EQ(speech[0].last, 52);
}

TEST_F(EvalPlotTest, MalformedAlignLineNamesFileAndLine) {
  // The last: a word 2.4 million frames long, which made eval --align enumerate them all
  // (found by fuzz_align).
  // And a word that starts before the one above ends.
  for (const char* bad_line :
       {"100 abc bin", "2000 1000 bin", "100 200", "100 200 bin extra", "070 2375050070 23", "50 200 bin"}) {
    const auto path = write("bad.align", std::string("0 100 sil\n") + bad_line + "\n");
    const CommandError error = error_of([&] { read_grid_align(path); }, fmt::format("accepted '{}'", bad_line));
    EXPECT_THAT(error.what(), HasSubstr(path.string() + ":2")) << bad_line;
  }
}

// A transcript with no word (an empty or blank file) or a folder given as one is an error, not
// a closure metric quietly left out (both read as no words and `eval` exited 0).
TEST_F(EvalPlotTest, AnAlignmentWithoutWordsOrAFolderIsAnError) {
  for (const char* text : {"", "\n\n  \n"}) {
    const auto path = write("empty.align", text);
    const CommandError error = error_of([&] { read_grid_align(path); }, "an alignment without words was accepted");
    EXPECT_EQ(error.exit_code(), kExitDataError);
    EXPECT_THAT(error.what(), HasSubstr(path.string() + ": no words"));
  }
  const fs::path folder = dir_ / "folder.align";
  fs::create_directory(folder);
  const CommandError error = error_of([&] { read_grid_align(folder); }, "a folder was accepted as an alignment");
  EXPECT_EQ(error.exit_code(), kExitNoInput);
  EXPECT_THAT(error.what(), HasSubstr(folder.string()));
}

/// Distinct saturated hues with at least `min_pixels` pixels: the line colours.
int line_colour_count(const cv::Mat& image, int min_pixels) {
  cv::Mat hsv;
  cv::cvtColor(image, hsv, cv::COLOR_BGR2HSV);
  std::vector<int> hue_bins(18, 0);  // OpenCV hue is 0-179
  for (int y = 0; y < hsv.rows; ++y) {
    for (int x = 0; x < hsv.cols; ++x) {
      const auto& p = hsv.at<cv::Vec3b>(y, x);
      if (p[1] > 120 && p[2] > 80) ++hue_bins[p[0] / 10];
    }
  }
  int colours = 0;
  for (int count : hue_bins) colours += count >= min_pixels ? 1 : 0;
  return colours;
}

/// 100 frames of smooth mouth motion with an untracked gap at frames 40-49.
std::string sine_csv(double phase) {
  std::ostringstream text;
  text << "frame,time_s,tracked,width_2d,height_2d\n";
  for (int frame = 0; frame < 100; ++frame) {
    const double t = frame / 25.0;
    text << frame << ',' << t;
    if (frame >= 40 && frame < 50) {
      text << ",0,,\n";
    } else {
      text << ",1," << std::sin(t * 3 + phase) << ',' << 0.5 + 0.4 * std::cos(t * 5 + phase) << '\n';
    }
  }
  return text.str();
}

TEST_F(EvalPlotTest, PlotWritesARequestedSizeImageWithOneColourPerFile) {
  const auto a = write("a.csv", sine_csv(0));
  const auto b = write("b.csv", sine_csv(1.5));
  const auto two = dir_ / "two.png";
  const RunResult result = run({"plot", a, b, "--columns", "width_2d,height_2d", "--out", two, "--width", "640",
                                "--height", "480", "--title", "two takes"});
  ASSERT_EQ(result.exit_code, 0) << result.err;
  const cv::Mat image = cv::imread(two.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(image.empty());
  EXPECT_EQ(image.cols, 640);
  EXPECT_EQ(image.rows, 480);
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero(grey < 250), 2000);  // not blank
  EXPECT_EQ(line_colour_count(image, 300), 2);

  const auto one = dir_ / "one.png";
  ASSERT_EQ(run({"plot", a, "--columns", "width_2d", "--out", one}).exit_code, 0);
  EXPECT_EQ(line_colour_count(cv::imread(one.string(), cv::IMREAD_COLOR), 300), 1);
}

TEST_F(EvalPlotTest, PlotOfValuesThatDifferInTheirLastDigitIsAConstantLine) {
  const auto near = write("near.csv", "frame,time_s,open\n0,0,0.3\n1,0.04,0.30000000000000004\n2,0.08,0.3\n");
  const auto png = dir_ / "near.png";
  // Under `timeout`: a plot whose ticks never pass the range's end runs until the memory is gone.
  const RunResult result = run({"plot", near, "--columns", "open", "--out", png}, "timeout 60 ");
  ASSERT_EQ(result.exit_code, 0) << result.err;
  EXPECT_EQ(line_colour_count(cv::imread(png.string(), cv::IMREAD_COLOR), 300), 1);
}

TEST_F(EvalPlotTest, PlotRefusesARepeatedColumnAndMorePanelsThanFitTheHeightLimit) {
  const auto a = write("a.csv", sine_csv(0));
  const auto png = (dir_ / "x.png").string();
  const RunResult twice = run({"plot", a, "--columns", "width_2d,height_2d,width_2d", "--out", png});
  EXPECT_EQ(twice.exit_code, 64);
  EXPECT_THAT(twice.err, HasSubstr("--columns: width_2d is given twice"));

  // 50 panels of 240 px make an image 13878 px high (it took 860 MB at 100 panels).
  std::string header = "frame,time_s", row = "0,0";
  std::string columns;
  for (int i = 0; i < 50; ++i) {
    header += fmt::format(",c{}", i);
    row += ",1";
    columns += fmt::format("{}c{}", i == 0 ? "" : ",", i);
  }
  const auto wide = write("wide.csv", header + "\n" + row + "\n");
  const RunResult tall = run({"plot", wide, "--columns", columns, "--out", png, "--width", "10000"});
  EXPECT_EQ(tall.exit_code, 64);
  EXPECT_THAT(tall.err, HasSubstr("--columns: 50 panels of 240 px"));
  EXPECT_THAT(tall.err, HasSubstr("(35 panels fit)"));
  // With --height: 50 panels in 2000 px leave each less than the smallest a panel may be.
  const RunResult squeezed = run({"plot", wide, "--columns", columns, "--out", png, "--height", "2000"});
  EXPECT_EQ(squeezed.exit_code, 64);
  EXPECT_THAT(squeezed.err, HasSubstr("--width/--height: 1000x2000 pixels is too small for 50 panel(s)"));
  EXPECT_FALSE(fs::exists(png));
}

TEST_F(EvalPlotTest, PlotOfAMissingColumnFails) {
  const auto a = write("a.csv", sine_csv(0));
  const RunResult result = run({"plot", a, "--columns", "protrusion_side", "--out", (dir_ / "x.png").string()});
  EXPECT_EQ(result.exit_code, 65);
  EXPECT_THAT(result.err, HasSubstr("protrusion_side"));
  EXPECT_FALSE(fs::exists(dir_ / "x.png"));
}

}  // namespace
}  // namespace lipdrive
