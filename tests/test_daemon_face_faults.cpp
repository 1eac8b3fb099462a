// `lipdrive run` on the simulated camera replaying a clip in which the face is replaced: a cut
// to another face 120 px aside, then a hand over the lens, then the face again
// (sim/face_faults.hpp). The take the daemon records must show no frame tracked on anything
// but the face in view (a tracked row's mouth measures are those of that face, measured on
// its own clip), no frame tracked while the lens is covered (the fail-safe drives those),
// and the face tracked again right after the cut and after the cover.
#include "daemon_process.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"
#include "shared_predictor.hpp"
#include "sim/face_faults.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// The clip: the generated face for kCut frames; then the same portrait mirrored (another face)
// and moved kShift px aside; from kCoverStart to kCoverEnd the lens is covered; then the
// mirrored face again until the end.
constexpr int kCut = 60, kCoverStart = 120, kCoverEnd = 140;
constexpr double kShift = 120;
// A tracked row is on the face when its inner-lip width and height (over d) are those of the
// face's own measurement to the take's precision (6 decimals).
constexpr double kTolerance = 2e-6;

enum class Shot { kFace, kOtherFace, kCovered };

Shot shot_of(int frame) {
  if (frame < kCut) return Shot::kFace;
  if (frame >= kCoverStart && frame < kCoverEnd) return Shot::kCovered;
  return Shot::kOtherFace;
}

std::vector<cv::Mat> read_gray(const fs::path& video) {
  std::vector<cv::Mat> frames;
  cv::VideoCapture capture(video.string());
  cv::Mat bgr, gray;
  while (capture.read(bgr)) {
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
    frames.push_back(gray.clone());
  }
  return frames;
}

/// Writes the clip as MJPEG (the fixture generator's codec) and returns its frames as decoded.
std::vector<cv::Mat> write_fault_clip(const std::vector<cv::Mat>& clean, const fs::path& path) {
  cv::VideoWriter video(path.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 25,
                        clean.front().size());
  EXPECT_TRUE(video.isOpened()) << path;
  for (int f = 0; f < static_cast<int>(clean.size()); ++f) {
    cv::Mat frame = clean[f];
    if (shot_of(f) != Shot::kFace) {
      cv::Mat mirrored;
      cv::flip(clean[f], mirrored, 1);
      frame = shifted_frame(mirrored, kShift, 0);
      if (shot_of(f) == Shot::kCovered) frame = covered_frame(frame, 1.0, 30, static_cast<std::uint64_t>(f));
    }
    cv::Mat bgr;
    cv::cvtColor(frame, bgr, cv::COLOR_GRAY2BGR);
    video.write(bgr);
  }
  video.release();
  return read_gray(path);
}

/// The face's own mouth measures at each of `processed` (the frames the daemon processed, in
/// order; it drops frames when it falls behind): each shot with a face in view through a
/// per-frame step of its own, fed the same frames from the first one the daemon saw of that
/// shot, so that it knows nothing of what came before the shot. A daemon that carried
/// anything over from the previous shot (a box, a template) measures something else. NaN
/// where not tracked, and for covered frames.
struct Truth {
  std::vector<double> width, height;
};

Truth face_truth(const std::vector<cv::Mat>& frames, const std::vector<int>& processed) {
  static const MorphableModel model = load_model_file(test::kModel);
  Truth truth{std::vector<double>(processed.size(), std::nan("")), std::vector<double>(processed.size(), std::nan(""))};
  std::optional<FrameProcessor> processor;
  std::optional<Shot> shot;
  for (std::size_t r = 0; r < processed.size(); ++r) {
    const int f = processed[r];
    if (shot != shot_of(f)) processor.emplace(model, LandmarkSet::F4, FitSettings{}, test::shared_predictor());
    shot = shot_of(f);
    if (shot == Shot::kCovered) continue;
    const FrameMeasurement& m = processor->process(frames[f], cv::Mat());
    if (m.tracked) truth.width[r] = m.measures.width_2d, truth.height[r] = m.measures.height_2d;
  }
  return truth;
}

TEST(DaemonFaceFaults, NoFrameIsDrivenFromWhatReplacedTheFace) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  LIPDRIVE_REQUIRE_BUILT(test::kModel);
  const std::vector<cv::Mat> clean = read_gray(test::kClip);
  ASSERT_GT(static_cast<int>(clean.size()), kCoverEnd + 30);
  const test::TempDir dir;
  const fs::path clip = dir.path() / "cut_and_covered.avi";
  const std::vector<cv::Mat> frames = write_fault_clip(clean, clip);
  ASSERT_EQ(frames.size(), clean.size());

  const fs::path takes = dir.path() / "takes";
  const fs::path config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << fmt::format(
      "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\nreal_time = true\nloop = false\nreplay_fps = 60\n"
      "[recording]\ndir = \"{}\"\nstart = true\nflush_interval_ms = 100\n[status]\nprint_interval_ms = 0\n",
      test::kModel.string(), clip.string(), takes.string());
  test::DaemonProcess daemon(config, dir.path() / "daemon.txt");
  ASSERT_EQ(daemon.wait(120s), 0) << "the daemon stops at the end of the recording\n" << daemon.log();

  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(takes)) files.push_back(entry.path());
  ASSERT_EQ(files.size(), 1u) << daemon.log();
  const CsvTable take = read_csv_table(files.front());
  const std::vector<double> frame = numeric_column(take, "frame"), tracked = numeric_column(take, "tracked"),
                            width = numeric_column(take, "width_2d"), height = numeric_column(take, "height_2d");

  std::vector<int> processed;
  for (const double f : frame) processed.push_back(static_cast<int>(f));
  const Truth truth = face_truth(frames, processed);

  int rows_on_face = 0, tracked_on_face = 0, off_face = 0, tracked_covered = 0;
  int first_after_cut = -1, first_after_cover = -1;  // the first rows at or after the cut and the cover's end
  bool tracked_after_cut = false, tracked_after_cover = false;
  double worst = 0;
  for (std::size_t r = 0; r < frame.size(); ++r) {
    const int f = static_cast<int>(frame[r]);
    ASSERT_GE(f, 0);
    ASSERT_LT(f, static_cast<int>(frames.size()));
    const Shot shot = shot_of(f);
    if (shot == Shot::kCovered) {
      tracked_covered += tracked[r] == 1;
      EXPECT_EQ(tracked[r], 0) << "frame " << f << ": tracked while the lens is covered";
      continue;
    }
    ++rows_on_face;
    if (f >= kCut && first_after_cut < 0) first_after_cut = f, tracked_after_cut = tracked[r] == 1;
    if (f >= kCoverEnd && first_after_cover < 0) first_after_cover = f, tracked_after_cover = tracked[r] == 1;
    if (tracked[r] != 1) continue;
    ++tracked_on_face;
    const double error = std::max(std::abs(width[r] - truth.width[r]), std::abs(height[r] - truth.height[r]));
    worst = std::max(worst, std::isnan(error) ? std::numeric_limits<double>::infinity() : error);
    if (!(error <= kTolerance)) {
      ++off_face;
      ADD_FAILURE() << "frame " << f << ": tracked with width " << width[r] << ", height " << height[r]
                    << " against the face's " << truth.width[r] << ", " << truth.height[r];
    }
  }
  RecordProperty("rows", static_cast<int>(frame.size()));
  RecordProperty("tracked_off_face", off_face);
  RecordProperty("tracked_covered", tracked_covered);
  RecordProperty("tracked_with_the_face_in_view", fmt::format("{}/{}", tracked_on_face, rows_on_face));
  fmt::print(
      "{} rows of {} frames; {} of {} rows with a face in view tracked, {} off the face (worst measure error "
      "{:.4f}), {} tracked while covered; first row after the cut: frame {} ({}), after the cover: frame {} ({})\n",
      frame.size(), frames.size(), tracked_on_face, rows_on_face, off_face, worst, tracked_covered, first_after_cut,
      tracked_after_cut ? "tracked" : "not tracked", first_after_cover,
      tracked_after_cover ? "tracked" : "not tracked");
  // Frames are dropped only when processing falls behind: a loaded machine drops more, and
  // while the lens is covered the detector runs on every frame (tens of milliseconds at 60 fps).
  // Every stretch of the clip is in the take, each with rows enough to say what happened there.
  const auto rows_between = [&](int first, int end) {
    return std::count_if(frame.begin(), frame.end(), [&](double f) { return f >= first && f < end; });
  };
  for (const auto& [first, end] : {std::pair{0, kCut}, std::pair{kCut, kCoverStart}, std::pair{kCoverStart, kCoverEnd},
                                   std::pair{kCoverEnd, static_cast<int>(frames.size())}})
    EXPECT_GE(rows_between(first, end), 3) << "frames " << first << ".." << end - 1 << "\n" << daemon.log();
  EXPECT_EQ(off_face, 0);
  EXPECT_EQ(tracked_covered, 0);
  // The real face is tracked again at once: the cut re-detects in its first frame, the
  // detector finds the face in the first frame without the hand, and no frame with the whole
  // face in view goes untracked.
  EXPECT_TRUE(tracked_after_cut) << "frame " << first_after_cut;
  EXPECT_TRUE(tracked_after_cover) << "frame " << first_after_cover;
  EXPECT_EQ(tracked_on_face, rows_on_face);
}

}  // namespace
}  // namespace lipdrive
