// The lip-closure evaluation over the shared recordings (skips without ../shared or
// $LIPDRIVE_SHARED_DIR): the closure metric (core/metrics.hpp) of `open`, against the landmark
// and fit heights it replaces, on the 50 GRID development clips and the two GRID fixtures;
// and on the 58 annotated LFPW photographs the landmark error and `open` against the
// annotated inner-lip height. Figures are printed and recorded as test properties
// (--gtest_output=xml).
//
// The lip-contact thresholds (core/lip_contact.hpp) were set on the first 25 GRID development
// clips in file-name order and nothing else; the other 25 and fixtures/grid are the check
// half, reported apart. The LFPW photographs were looked at while designing the measure
// (first half in file-name order only); both halves are reported apart.
//
// Clips and photographs are decoded as the simulated camera and `lipdrive process` decode them
// (FFmpeg's luma and Cr planes, drivers/video_file.hpp); the GRID clips run in colour and in
// their luma alone, as a monochrome camera would give them.
#include "core/metrics.hpp"
#include "core/statistics.hpp"
#include "drivers/video_file.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/predictor_file.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/tables/grid_align.hpp"
#include "fixture_paths.hpp"
#include "shared_predictor.hpp"
#include "sim/steady_take.hpp"

#include <dlib/image_processing/frontal_face_detector.h>
#include <dlib/opencv/cv_image.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/core/mat.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const MorphableModel& default_model() {
  static const MorphableModel model = load_model_file(test::kModel);
  return model;
}

std::vector<fs::path> files_with_extension(const fs::path& dir, const std::string& extension) {
  std::vector<fs::path> files;
  if (!fs::is_directory(dir)) return files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().extension() == extension) files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

// ---------------------------------------------------------------------------------------------
// GRID

/// The series of one clip that the closure metric scores.
struct ClipSeries {
  std::string name;
  std::vector<double> open, height_2d, height_fit, bilabial_viseme;
  int frames = 0, tracked = 0, lost_after_acquired = 0;
  std::vector<WordFrames> words;
  std::vector<AlignedWord> align;  // owns the words' text
};

/// A clip through the per-frame step as the simulated camera decodes it; `colour` false: its
/// luma alone, as a monochrome camera gives it.
ClipSeries process_clip(const fs::path& video, bool colour) {
  ClipSeries clip;
  clip.name = video.stem().string();
  clip.align = read_grid_align(fs::path(video).replace_extension(".align"));
  clip.words = word_frames(clip.align, kGridFramesPerSecond);
  FrameProcessor processor(default_model(), LandmarkSet::F4, FitSettings{}, test::shared_predictor());
  VideoFile file(video);
  cv::Mat gray, cr;
  bool acquired = false;
  while (file.read(gray, cr)) {
    const FrameMeasurement& m = processor.process(gray, colour ? cr : cv::Mat());
    ++clip.frames;
    clip.tracked += m.tracked;
    clip.lost_after_acquired += acquired && !m.tracked;
    acquired = acquired || m.tracked;
    clip.open.push_back(m.tracked ? m.measures.open : kNaN);
    clip.height_2d.push_back(m.tracked ? m.measures.height_2d : kNaN);
    clip.height_fit.push_back(m.tracked ? m.measures.height_fit : kNaN);
    clip.bilabial_viseme.push_back(m.tracked ? m.visemes[2] : kNaN);  // kVisemeNames[2] = B-M-P
  }
  return clip;
}

/// The per-clip conditions on a series.
bool meets_clip_conditions(const ClosureMetric& m) {
  return m.opening >= 0.5 && m.silence_median <= 0.15 && m.silence_jitter <= 0.02;
}

struct HalfFigures {
  int clips = 0, words = 0, closures = 0, clips_failing = 0;
  double worst_opening = 1, worst_silence = 0, worst_jitter = 0;
  std::vector<std::string> misses;  // "clip:word@frame (minimum)" and "clip: opening ..."
};

HalfFigures score(const std::vector<ClipSeries>& clips, std::vector<double> ClipSeries::*series) {
  HalfFigures h;
  for (const ClipSeries& clip : clips) {
    const ClosureMetric m = closure_metric(clip.*series, clip.words, kGridFramesPerSecond);
    ++h.clips;
    h.words += m.bilabial_words;
    h.closures += m.closures_seen;
    for (const WordClosure& w : m.words)
      if (!w.closed) h.misses.push_back(fmt::format("{}:{}@{} ({:.2f})", clip.name, w.word, w.first, w.minimum));
    if (!meets_clip_conditions(m)) {
      ++h.clips_failing;
      h.misses.push_back(fmt::format("{}: opening {:.2f}, final silence {:.2f}, jitter {:.3f}", clip.name, m.opening,
                                     m.silence_median, m.silence_jitter));
    }
    h.worst_opening = std::min(h.worst_opening, m.opening);
    h.worst_silence = std::max(h.worst_silence, m.silence_median);
    h.worst_jitter = std::max(h.worst_jitter, m.silence_jitter);
  }
  return h;
}

std::string summary(const HalfFigures& h) {
  return fmt::format(
      "closures {}/{} ({:.1f} %), clips failing opening/silence/jitter {}/{} (lowest opening {:.2f}, "
      "highest final silence {:.2f}, highest jitter {:.3f})",
      h.closures, h.words, 100.0 * h.closures / std::max(h.words, 1), h.clips_failing, h.clips, h.worst_opening,
      h.worst_silence, h.worst_jitter);
}

/// B-M-P reaches 0.5 somewhere in each bilabial word (widened by 2 frames), and its mean over
/// the final silences.
std::pair<std::string, double> bilabial_viseme_figure(const std::vector<ClipSeries>& clips) {
  int words = 0, reached = 0;
  double rest_sum = 0;
  int rest_frames = 0;
  for (const ClipSeries& clip : clips) {
    const int n = static_cast<int>(clip.bilabial_viseme.size());
    for (const WordFrames& w : clip.words) {
      if (w.silence) continue;
      if (!is_bilabial_word(w.word)) continue;
      ++words;
      double best = 0;
      for (int f = std::max(0, w.first - 2); f <= std::min(n - 1, w.last + 2); ++f)
        if (std::isfinite(clip.bilabial_viseme[f])) best = std::max(best, clip.bilabial_viseme[f]);
      reached += best >= 0.5;
    }
    const auto last =
        std::find_if(clip.words.rbegin(), clip.words.rend(), [](const WordFrames& w) { return w.silence; });
    if (last == clip.words.rend()) continue;
    for (int f = last->first + 3; f <= std::min(n - 1, last->last); ++f)
      if (std::isfinite(clip.bilabial_viseme[f])) rest_sum += clip.bilabial_viseme[f], ++rest_frames;
  }
  return {fmt::format("{}/{}", reached, words), rest_frames ? rest_sum / rest_frames : kNaN};
}

TEST(LipClosureEvaluation, GridClosuresOnTuningAndCheckClips) {
  const fs::path shared = test::shared_fixtures();
  LIPDRIVE_SKIP_WITHOUT_SHARED(shared / "grid_train");
  const std::vector<fs::path> development = files_with_extension(shared / "grid_train", ".mpg");
  const std::vector<fs::path> fixtures = files_with_extension(shared / "grid", ".mpg");
  ASSERT_GE(development.size(), 2u) << "no GRID clips in " << shared / "grid_train";
  const std::size_t tuning_count = development.size() / 2;  // the first half in file-name order
  // In colour (GRID's clips are), and in their luma alone: a monochrome camera (an infrared rig)
  // must meet the same bounds.
  for (const bool colour : {true, false}) {
    const std::string planes = colour ? "colour" : "luma alone";
    std::vector<ClipSeries> tuning, check;
    for (std::size_t i = 0; i < development.size(); ++i)
      (i < tuning_count ? tuning : check).push_back(process_clip(development[i], colour));
    for (const fs::path& clip : fixtures) check.push_back(process_clip(clip, colour));

    for (const auto& [half_name, clips] : {std::pair{"tuning", &tuning}, std::pair{"check", &check}}) {
      const std::string half = colour ? std::string(half_name) : std::string(half_name) + "_luma";
      SCOPED_TRACE(planes);
      int frames = 0, tracked = 0, lost = 0;
      for (const ClipSeries& clip : *clips) {
        frames += clip.frames, tracked += clip.tracked, lost += clip.lost_after_acquired;
        EXPECT_EQ(clip.lost_after_acquired, 0) << clip.name << ": the track was dropped on a GRID face";
      }
      const HalfFigures open = score(*clips, &ClipSeries::open);
      const HalfFigures landmarks = score(*clips, &ClipSeries::height_2d);
      const HalfFigures fit = score(*clips, &ClipSeries::height_fit);
      const auto [bmp_words, bmp_rest] = bilabial_viseme_figure(*clips);
      fmt::print("GRID {} half ({}), {} clips, {} frames, {} tracked, {} lost after acquisition\n", half_name, planes,
                 clips->size(), frames, tracked, lost);
      fmt::print("  open        {}\n  height_2d   {}\n  height_fit  {}\n", summary(open), summary(landmarks),
                 summary(fit));
      fmt::print("  viseme B-M-P >= 0.5 on {} bilabial words; mean {:.3f} in the final silences\n", bmp_words,
                 bmp_rest);
      for (const std::string& miss : open.misses) fmt::print("  open miss: {}\n", miss);
      ::testing::Test::RecordProperty(fmt::format("grid_{}_open", half), summary(open));
      ::testing::Test::RecordProperty(fmt::format("grid_{}_height_2d", half), summary(landmarks));
      ::testing::Test::RecordProperty(fmt::format("grid_{}_height_fit", half), summary(fit));
      ::testing::Test::RecordProperty(fmt::format("grid_{}_bmp_viseme", half),
                                      fmt::format("{} words, rest {:.3f}", bmp_words, bmp_rest));

      // What drives the figure shows at least the closures the raw landmarks show, and 95 % of all.
      EXPECT_GE(open.closures, landmarks.closures) << half;
      EXPECT_GE(open.closures, 0.95 * open.words) << half;
      // Every clip opens, rests and keeps still in its final silence: on the clips the thresholds
      // were set on, all of them; on the check clips, no fewer than with the landmark height.
      if (std::string(half_name) == "tuning")
        EXPECT_EQ(open.clips_failing, 0);
      else
        EXPECT_LE(open.clips_failing, landmarks.clips_failing);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// LFPW

/// 300-W .pts: 68 points, 1-based pixel coordinates.
Landmarks2D read_pts(const fs::path& path) {
  std::ifstream in(path);
  std::string token;
  while (in >> token && token != "{") {
  }
  Landmarks2D p;
  for (int i = 0; i < kNumLandmarks; ++i) in >> p(0, i) >> p(1, i);
  if (!in) throw std::runtime_error(path.string() + ": not 68 points");
  return p.array() - 1.0;
}

struct PhotoResult {
  std::string name;
  bool tracked = false;
  double point_error = kNaN;  // mean over the 68 points, over the annotated outer-eye-corner distance
  double truth_height = 0, open = kNaN, height_2d = kNaN, seal = kNaN;
};

/// One photograph through the per-frame step, detected afresh. With `crop`, the image is cut
/// to the annotated face and its surroundings first, so that the detector's largest face is
/// the annotated one in photographs of several people. `detected`: dlib's HOG detector finds
/// a face whose box holds the annotated nose tip, and the annotated face is inside the image
/// by 5 % of its outer-eye-corner distance (the tracker rejects landmarks off the image).
PhotoResult process_photo(FrameProcessor& processor, const fs::path& image, bool crop, bool* detected = nullptr) {
  PhotoResult r;
  r.name = image.stem().string();
  const Landmarks2D truth = read_pts(fs::path(image).replace_extension(".pts"));
  r.truth_height = mouth_ratios<2>(truth).height;
  cv::Mat gray, cr;
  read_image(image, gray, cr);
  Eigen::Vector2d offset = Eigen::Vector2d::Zero();
  if (crop) {
    const Eigen::Vector2d low = truth.rowwise().minCoeff(), high = truth.rowwise().maxCoeff();
    const Eigen::Vector2d size = high - low;
    const int x0 = std::max(0, static_cast<int>(low.x() - size.x())),
              y0 = std::max(0, static_cast<int>(low.y() - size.y()));
    const int x1 = std::min(gray.cols, static_cast<int>(high.x() + size.x())),
              y1 = std::min(gray.rows, static_cast<int>(high.y() + size.y()));
    gray = gray(cv::Rect(x0, y0, x1 - x0, y1 - y0)).clone();
    if (!cr.empty()) cr = cr(cv::Rect(x0, y0, x1 - x0, y1 - y0)).clone();
    offset << x0, y0;
  }
  if (detected) {
    static dlib::frontal_face_detector detector = dlib::get_frontal_face_detector();
    const Eigen::Vector2d nose = truth.col(ibug::kNoseTip) - offset;
    *detected = false;
    for (const dlib::rectangle& box : detector(dlib::cv_image<unsigned char>(gray)))
      *detected = *detected || box.contains(static_cast<long>(nose.x()), static_cast<long>(nose.y()));
    const double margin = 0.05 * interocular_distance(truth);
    const Landmarks2D local = truth.colwise() - offset;
    *detected = *detected && local.minCoeff() >= margin && local.row(0).maxCoeff() <= gray.cols - 1 - margin &&
                local.row(1).maxCoeff() <= gray.rows - 1 - margin;
  }
  processor.forget(FaceTracker::Next::kStill);
  const FrameMeasurement& m = processor.process(gray, cr);
  r.tracked = m.tracked;
  if (!m.tracked) return r;
  const Landmarks2D landmarks = m.landmarks.colwise() + offset;
  r.point_error = (landmarks - truth).colwise().norm().mean() / interocular_distance(truth);
  r.open = m.measures.open;
  r.height_2d = m.measures.height_2d;
  r.seal = m.measures.seal;
  return r;
}

struct PhotoFigures {
  int photos = 0, tracked = 0;
  double point_error = 0, open_mae = 0, landmark_mae = 0;
  std::vector<std::string> untracked;
  std::vector<double> closed_open, closed_seal;  // annotated gap 0
};

PhotoFigures photo_figures(const std::vector<PhotoResult>& results) {
  PhotoFigures f;
  for (const PhotoResult& r : results) {
    ++f.photos;
    if (!r.tracked) {
      f.untracked.push_back(r.name);
      continue;
    }
    ++f.tracked;
    f.point_error += r.point_error;
    f.open_mae += std::abs(r.open - r.truth_height);
    f.landmark_mae += std::abs(r.height_2d - r.truth_height);
    if (r.truth_height == 0) f.closed_open.push_back(r.open), f.closed_seal.push_back(r.seal);
  }
  f.point_error /= std::max(f.tracked, 1);
  f.open_mae /= std::max(f.tracked, 1);
  f.landmark_mae /= std::max(f.tracked, 1);
  return f;
}

std::string distribution(std::vector<double> v) {
  if (v.empty()) return "none";
  const std::size_t n = v.size();
  const double q10 = quantile(v, 0.1), q50 = median(v), q90 = quantile(v, 0.9);
  return fmt::format("min {:.3f}, 10 % {:.3f}, median {:.3f}, 90 % {:.3f}, max {:.3f} (n {})",
                     *std::min_element(v.begin(), v.end()), q10, q50, q90, *std::max_element(v.begin(), v.end()), n);
}

TEST(LipClosureEvaluation, LfpwPhotographs) {
  LIPDRIVE_SKIP_WITHOUT_SHARED(test::shared_fixtures() / "lfpw_train");
  const std::vector<fs::path> photos = files_with_extension(test::shared_fixtures() / "lfpw_train", ".png");
  ASSERT_FALSE(photos.empty()) << "no photographs in " << test::shared_fixtures() / "lfpw_train";
  // Searched as `lipdrive process` searches stills: dlib's detector, then OpenCV's face cascade.
  const TrackerSettings stills{.still_cascade = load_still_cascade()};
  FrameProcessor processor(default_model(), LandmarkSet::F4, FitSettings{}, test::shared_predictor(), {},
                           FitOutput::Expressions::Zero(), {}, stills);
  std::vector<PhotoResult> cropped, whole;
  std::string by_cascade;
  for (const fs::path& photo : photos) {
    bool detected = false;
    cropped.push_back(process_photo(processor, photo, true, &detected));
    // The checks never reject a face the detector found.
    EXPECT_TRUE(cropped.back().tracked || !detected) << photo << ": detected, but not tracked";
    if (cropped.back().tracked && !detected)
      by_cascade += fmt::format(" {} (point error {:.4f})", cropped.back().name, cropped.back().point_error);
    whole.push_back(process_photo(processor, photo, false));
  }
  fmt::print("LFPW tracked where dlib's detector finds no face at the photograph's own size:{}\n",
             by_cascade.empty() ? " none" : by_cascade);
  const std::size_t half = photos.size() / 2;
  const std::vector<PhotoResult> first(cropped.begin(), cropped.begin() + static_cast<long>(half)),
      second(cropped.begin() + static_cast<long>(half), cropped.end());
  using Set = std::pair<const char*, const std::vector<PhotoResult>*>;
  for (const auto& [name, results] :
       {Set{"all", &cropped}, Set{"first half", &first}, Set{"second half", &second}, Set{"whole images", &whole}}) {
    const PhotoFigures f = photo_figures(*results);
    std::string untracked;
    for (const std::string& u : f.untracked) untracked += " " + u;
    const std::string line = fmt::format(
        "{}/{} tracked, mean point error {:.4f} of the outer-eye-corner distance, open MAE {:.4f} H/d (landmarks "
        "alone {:.4f}); closed mouths: open {}, seal {}; untracked:{}",
        f.tracked, f.photos, f.point_error, f.open_mae, f.landmark_mae, distribution(f.closed_open),
        distribution(f.closed_seal), untracked.empty() ? " none" : untracked);
    fmt::print("LFPW {}: {}\n", name, line);
    ::testing::Test::RecordProperty(fmt::format("lfpw_{}", name), line);
  }
  const PhotoFigures all = photo_figures(cropped);
  if (stills.still_cascade) {
    EXPECT_EQ(all.tracked, all.photos) << "the issue: every frontal face tracked";
  }
  EXPECT_LE(all.point_error, 0.030);
  EXPECT_LE(all.open_mae, 0.04);  // the bound (0.0451 before acquisition took the median of seven starts)
  EXPECT_LE(all.open_mae, all.landmark_mae) << "open is further from the annotation than the landmark height";
  // Sealed lips read sealed: the median closed mouth has seal > 0.5 and open below 0.01 d.
  std::vector<double> seal = all.closed_seal, open = all.closed_open;
  ASSERT_FALSE(seal.empty());
  EXPECT_GT(median(seal), 0.5);
  EXPECT_LT(median(open), 0.01);
}

// ---------------------------------------------------------------------------------------------
// LFPW faces as steady takes

// Each photograph's face as a 3 s take from a head-mounted camera (sim/steady_take: swaying a
// little, the light breathing, sensor noise), tracked from frame to frame as the daemon tracks.
// The tracker's checks were set on one GRID speaker and the generated face; here they meet 58
// faces (beards, glasses, make-up, skin tones, hands at the face). No tracked frame may be off
// the face. The frames lost, and the error against the annotation, are reported.
//
// Off the face: in the fault clips of test_face_tracker, more than 0.1 inter-ocular distances
// from the same face's landmarks in the clean clip, tracked by the same build. Here the face's
// own landmarks are the photograph's, carried into the frame: at another size, without the
// take's noise, so they carry the predictor's own wobble on a hard face (image_0072, behind
// thick-rimmed glasses: 0.107 from them in two frames of the clang ASan build, the annotation
// 0.093 and 0.088 away; docs/method.md 1, "Lips crossed under a moustache"). An acquisition
// that stretched the face to its chin read 0.27 (image_0406 close to the camera, before an
// acquired face's box settled in a camera's frames). So the bound here is twice the fault
// clips'; the frames beyond theirs, and the largest distance, are reported.
constexpr double kOffTheFace = 0.2;

// Every photograph's take, its face `interocular_px` between the outer eye corners, tracked
// with `tracking`; the summary printed and recorded as the test property `property`.
void expect_steady_takes_on_the_face(double interocular_px, TrackerSettings tracking, const std::string& property) {
  LIPDRIVE_SKIP_WITHOUT_SHARED(test::shared_fixtures() / "lfpw_train");
  const std::vector<fs::path> photos = files_with_extension(test::shared_fixtures() / "lfpw_train", ".png");
  ASSERT_FALSE(photos.empty()) << "no photographs in " << test::shared_fixtures() / "lfpw_train";
  constexpr int kFrames = 75;
  FrameProcessor processor(default_model(), LandmarkSet::F4, FitSettings{}, test::shared_predictor(), Eigen::VectorXf(),
                           FitOutput::Expressions::Zero(), AutoIdentity{}, tracking);
  int frames = 0, tracked = 0, off_the_face = 0, beyond_fault_bound = 0, whole_takes = 0;
  double error_sum = 0, farthest = 0;
  std::string losing;
  for (const fs::path& photo : photos) {
    const Landmarks2D truth = read_pts(fs::path(photo).replace_extension(".pts"));
    cv::Mat gray, cr;
    read_image(photo, gray, cr);
    const SteadyTake take = steady_take(gray, truth, kFrames, interocular_px);
    processor.forget(FaceTracker::Next::kStill);
    const FrameMeasurement& still = processor.process(gray, cv::Mat());
    const Landmarks2D own = still.tracked ? still.landmarks : truth;
    processor.forget(FaceTracker::Next::kVideo);
    int first = -1, lost = 0;
    for (int f = 0; f < kFrames; ++f) {
      const FrameMeasurement& m = processor.process(take.frames[static_cast<std::size_t>(f)], cv::Mat());
      ++frames;
      if (!m.tracked) {
        lost += first >= 0;
        continue;
      }
      if (first < 0) first = f;
      ++tracked;
      const auto error = [&](const Landmarks2D& photographed) {
        const Landmarks2D face = take.in_frame(static_cast<std::size_t>(f), photographed);
        return (m.landmarks - face).colwise().norm().mean() / interocular_distance(face);
      };
      error_sum += error(truth);
      const double from_own = error(own);
      farthest = std::max(farthest, from_own);
      beyond_fault_bound += from_own > 0.1;
      off_the_face += from_own > kOffTheFace;
    }
    if (first == 0 && lost == 0)
      ++whole_takes;
    else
      losing += first < 0 ? fmt::format(" {} (never)", photo.stem().string())
                          : fmt::format(" {} (from frame {}, {} lost after)", photo.stem().string(), first, lost);
  }
  const std::string line = fmt::format(
      "{} takes of {} frames, {} px between the eyes: {} tracked on every frame; {}/{} frames tracked, mean point "
      "error {:.4f} (of the annotation); from the photograph's own landmarks at most {:.3f}, {} frames beyond 0.1, {} "
      "off the face (beyond {}); the others:{}",
      photos.size(), kFrames, interocular_px, whole_takes, tracked, frames, error_sum / std::max(tracked, 1), farthest,
      beyond_fault_bound, off_the_face, kOffTheFace, losing.empty() ? " none" : losing);
  fmt::print("LFPW steady takes: {}\n", line);
  ::testing::Test::RecordProperty(property, line);
  EXPECT_EQ(off_the_face, 0) << "frames tracked off the face";
}

TEST(LipClosureEvaluation, LfpwFacesAsSteadyTakes) {
  expect_steady_takes_on_the_face(90, TrackerSettings{}, "lfpw_steady_takes");
}

// The same faces close to the camera, as a head-mounted rig frames them, with `[tracker]
// min_face_px` set as the README tells such a rig to: near the face's width less a margin
// (1.5 outer-eye-corner distances; the detector's box around a face is wider). The detector's
// box then comes from a frame reduced 2.8 times, and the face must settle from it (image_0406,
// a child's grin behind glasses, was acquired stretched to the chin before it did).
TEST(LipClosureEvaluation, LfpwFacesCloseToTheCamera) {
  constexpr double kInterocularPx = 150;
  expect_steady_takes_on_the_face(kInterocularPx, TrackerSettings{.min_face_px = 1.5 * kInterocularPx},
                                  "lfpw_steady_takes_close");
}

}  // namespace
}  // namespace lipdrive
