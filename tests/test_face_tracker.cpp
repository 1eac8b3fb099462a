// The allocation-free ERT predictor against dlib's own, and the FaceTracker's
// acquire -> track -> lose -> re-acquire cycle.
#include "allocation_counter.hpp"
#include "core/face_tracker.hpp"
#include "core/shape_predictor.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "fixture_paths.hpp"
#include "shared_predictor.hpp"

#include <dlib/image_processing.h>
#include <dlib/image_processing/frontal_face_detector.h>
#include <dlib/opencv/cv_image.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace lipdrive {
namespace {

const std::filesystem::path kGridDir = test::shared_fixtures() / "grid";
const std::filesystem::path kFixtureDir = LIPDRIVE_FIXTURE_DIR;

std::vector<cv::Mat> read_gray_frames(const std::filesystem::path& video) {
  std::vector<cv::Mat> frames;
  cv::VideoCapture capture(video.string());
  cv::Mat bgr;
  while (capture.read(bgr)) {
    cv::Mat gray;
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
    frames.push_back(gray);
  }
  return frames;
}

std::vector<cv::Mat> grid_frames(const char* clip) {
  const auto path = kGridDir / (std::string(clip) + ".mpg");
  return std::filesystem::exists(path) ? read_gray_frames(path) : std::vector<cv::Mat>{};
}

// A face image the build makes itself: the generated talking-face fixture's first frame,
// or the portrait it is made from.
cv::Mat generated_face() {
  const auto video = kFixtureDir / "talking_face.avi";
  if (std::filesystem::exists(video)) {
    auto frames = read_gray_frames(video);
    if (!frames.empty()) return frames.front();
  }
  return cv::imread((kFixtureDir / "astronaut.png").string(), cv::IMREAD_GRAYSCALE);
}

const dlib::shape_predictor& dlib_predictor() {
  static const dlib::shape_predictor predictor = [] {
    dlib::shape_predictor p;
    dlib::deserialize(kDefaultPredictorPath) >> p;
    return p;
  }();
  return predictor;
}

dlib::frontal_face_detector& dlib_detector() {
  static dlib::frontal_face_detector detector = dlib::get_frontal_face_detector();
  return detector;
}

// Runs both predictors on `box` and expects identical decisions: the same leaf in every
// tree means the same leaf vectors summed in the same order, i.e. dlib's float shape
// exactly; dlib then rounds to whole pixels, ours keeps the sub-pixel position.
void expect_matches_dlib(const cv::Mat& gray, const dlib::rectangle& rect, const std::string& what) {
  ShapePredictor ours(test::shared_predictor());
  Landmarks2D landmarks;
  ours.predict(gray, FaceBox{rect.left(), rect.top(), rect.right(), rect.bottom()}, landmarks);

  std::vector<std::pair<unsigned long, double>> features;
  const dlib::full_object_detection theirs = dlib_predictor()(dlib::cv_image<unsigned char>(gray), rect, features);
  const auto leaves = ours.last_leaves();
  ASSERT_EQ(features.size(), leaves.size()) << what;
  const unsigned long leaves_per_tree = 1ul << test::shared_predictor()->tree_depth();
  int different_leaves = 0;
  for (std::size_t t = 0; t < leaves.size(); ++t)
    different_leaves += features[t].first - t * leaves_per_tree != leaves[t];
  EXPECT_EQ(different_leaves, 0) << what;

  ASSERT_EQ(theirs.num_parts(), static_cast<unsigned long>(kNumLandmarks));
  for (int i = 0; i < kNumLandmarks; ++i) {
    // floor(x + 0.5) is dlib's conversion to point.
    EXPECT_NEAR(landmarks(0, i), theirs.part(i).x(), 0.5 + 1e-3) << what << " landmark " << i;
    EXPECT_NEAR(landmarks(1, i), theirs.part(i).y(), 0.5 + 1e-3) << what << " landmark " << i;
  }
}

std::vector<dlib::rectangle> detect(const cv::Mat& gray) {
  return dlib_detector()(dlib::cv_image<unsigned char>(gray));
}

TEST(ShapePredictor, MatchesDlibOnGridFrames) {
  LIPDRIVE_SKIP_WITHOUT_SHARED(kGridDir / "bbaf2n.mpg");
  int compared = 0;
  for (const char* clip : {"bbaf2n", "lgaf4n"}) {
    const auto frames = grid_frames(clip);
    for (std::size_t f = 0; f < frames.size(); f += 7) {
      const auto faces = detect(frames[f]);
      ASSERT_FALSE(faces.empty()) << clip << " frame " << f;
      expect_matches_dlib(frames[f], faces.front(), std::string(clip) + " frame " + std::to_string(f));
      // A box that is shifted and partly outside the image: out-of-image pixels read 0.
      expect_matches_dlib(frames[f],
                          dlib::translate_rect(faces.front(), -static_cast<long>(faces.front().width()) / 2, 30),
                          std::string(clip) + " shifted box, frame " + std::to_string(f));
      ++compared;
    }
  }
  EXPECT_GT(compared, 0) << "no frames read from the GRID clips in " << kGridDir;
}

TEST(ShapePredictor, MatchesDlibOnGeneratedFace) {
  LIPDRIVE_REQUIRE_BUILT(kFixtureDir / "talking_face.avi");
  const cv::Mat face = generated_face();
  ASSERT_FALSE(face.empty()) << "no frame in " << kFixtureDir / "talking_face.avi";
  // Also a rotated, smaller copy: the similarity transform then has a real rotation part.
  cv::Mat rotated;
  const cv::Mat turn = cv::getRotationMatrix2D(cv::Point2f(face.cols / 2.f, face.rows / 2.f), 12, 0.7);
  cv::warpAffine(face, rotated, turn, face.size());
  for (const cv::Mat& image : {face, rotated}) {
    const auto faces = detect(image);
    ASSERT_FALSE(faces.empty());
    expect_matches_dlib(image, faces.front(), "generated face");
  }
}

TEST(ShapePredictor, RejectsFilesThatAreNotPredictors) {
  const auto dir = std::filesystem::temp_directory_path() / "lipdrive_test_predictor";
  std::filesystem::create_directories(dir);
  const auto text = dir / "notes.dat";
  std::ofstream(text) << "this is not a predictor\n";
  try {
    load_predictor_file(text);
    FAIL() << "a text file was accepted";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.exit_code(), kExitDataError);
    EXPECT_NE(std::string(e.what()).find(text.string()), std::string::npos) << e.what();
  }
  try {
    load_predictor_file(dir / "missing.dat");
    FAIL() << "a missing file was accepted";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.exit_code(), kExitNoInput);
    EXPECT_NE(std::string(e.what()).find("missing.dat"), std::string::npos) << e.what();
  }
  // A real dlib shape predictor with 5 landmarks, not 68.
  const auto five = dir / "five.dat";
  {
    dlib::matrix<float, 0, 1> shape(10);
    shape = 0.5;
    std::vector<std::vector<dlib::impl::regression_tree>> forests(1, std::vector<dlib::impl::regression_tree>(1));
    forests[0][0].splits.push_back({0, 0, 0.f});
    forests[0][0].leaf_values.assign(2, shape);
    const std::vector<std::vector<dlib::vector<float, 2>>> pixels(1, {dlib::vector<float, 2>(0.5f, 0.5f)});
    const dlib::shape_predictor predictor(shape, forests, pixels);
    dlib::serialize(five.string()) << predictor;
  }
  try {
    load_predictor_file(five);
    FAIL() << "a 5-landmark predictor was accepted";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.exit_code(), kExitDataError);
    EXPECT_NE(std::string(e.what()).find("5 landmarks"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

TEST(FaceTracker, AcquiresThenTracksAGridClip) {
  LIPDRIVE_SKIP_WITHOUT_SHARED(kGridDir / "bbaf2n.mpg");
  const auto frames = grid_frames("bbaf2n");
  ASSERT_FALSE(frames.empty()) << "no frames read from " << kGridDir / "bbaf2n.mpg";
  FaceTracker tracker(test::shared_predictor());
  ShapePredictor reference(test::shared_predictor());
  Landmarks2D tracked, detected;
  for (std::size_t f = 0; f < frames.size(); ++f) {
    const TrackStatus status = tracker.track(frames[f], tracked);
    ASSERT_EQ(status, f == 0 ? TrackStatus::kAcquired : TrackStatus::kTracking) << "frame " << f;
    // Tracking from the last landmarks' box must agree with a fresh detection.
    const auto faces = detect(frames[f]);
    ASSERT_FALSE(faces.empty());
    const auto& r = faces.front();
    reference.predict(frames[f], FaceBox{r.left(), r.top(), r.right(), r.bottom()}, detected);
    const double mean_distance = (tracked - detected).colwise().norm().mean();
    EXPECT_LT(mean_distance, 0.05 * interocular_distance(detected)) << "frame " << f;
  }
}

TEST(FaceTracker, LosesTheFaceOnABlankFrameAndReacquires) {
  auto frames = grid_frames("bbaf2n");
  if (frames.empty()) frames.assign(4, generated_face());
  if (frames.front().empty()) LIPDRIVE_REQUIRE_BUILT(kFixtureDir / "talking_face.avi");
  ASSERT_FALSE(frames.front().empty()) << "no face in the GRID clip or the generated fixture";
  FaceTracker tracker(test::shared_predictor());
  Landmarks2D landmarks;
  EXPECT_EQ(tracker.track(frames[0], landmarks), TrackStatus::kAcquired);
  EXPECT_EQ(tracker.track(frames[1], landmarks), TrackStatus::kTracking);
  const cv::Mat blank(frames[0].size(), CV_8UC1, cv::Scalar(128));
  EXPECT_EQ(tracker.track(blank, landmarks), TrackStatus::kNoFace);
  EXPECT_FALSE(tracker.tracking());
  EXPECT_EQ(tracker.track(blank, landmarks), TrackStatus::kNoFace);  // the detector finds nothing either
  EXPECT_EQ(tracker.track(frames[2], landmarks), TrackStatus::kAcquired);
  EXPECT_EQ(tracker.track(frames[3], landmarks), TrackStatus::kTracking);
}

TEST(FaceTracker, APoorFitDropsTheTrack) {
  LIPDRIVE_REQUIRE_BUILT(kFixtureDir / "talking_face.avi");
  const cv::Mat face = generated_face();
  ASSERT_FALSE(face.empty()) << "no frame in " << kFixtureDir / "talking_face.avi";
  FaceTracker tracker(test::shared_predictor());
  Landmarks2D landmarks;
  ASSERT_EQ(tracker.track(face, landmarks), TrackStatus::kAcquired);
  const double iod = interocular_distance(landmarks);
  EXPECT_TRUE(tracker.check_fit(landmarks, 0.02 * iod));
  EXPECT_TRUE(tracker.tracking());
  EXPECT_FALSE(tracker.check_fit(landmarks, 0.5 * iod));
  EXPECT_FALSE(tracker.tracking());
  EXPECT_EQ(tracker.track(face, landmarks), TrackStatus::kAcquired);
}

TEST(FaceTracker, ImplausibleLandmarksAreRejected) {
  LIPDRIVE_REQUIRE_BUILT(kFixtureDir / "talking_face.avi");
  const cv::Mat face = generated_face();
  ASSERT_FALSE(face.empty()) << "no frame in " << kFixtureDir / "talking_face.avi";
  FaceTracker tracker(test::shared_predictor());
  Landmarks2D landmarks;
  ASSERT_EQ(tracker.track(face, landmarks), TrackStatus::kAcquired);
  EXPECT_TRUE(plausible_face(landmarks, face.cols, face.rows, 12));
  Landmarks2D upside_down = landmarks;
  upside_down.row(1) = (face.rows - 1 - landmarks.row(1).array()).matrix();
  EXPECT_FALSE(plausible_face(upside_down, face.cols, face.rows, 12));
  Landmarks2D outside = landmarks;
  outside(0, 0) = -3;
  EXPECT_FALSE(plausible_face(outside, face.cols, face.rows, 12));
  Landmarks2D tiny = landmarks / 50.0;
  EXPECT_FALSE(plausible_face(tiny, face.cols, face.rows, 12));
}

TEST(FaceTracker, SteadyStateTrackingAllocatesNothing) {
  auto frames = grid_frames("bbaf2n");
  if (frames.empty()) frames.assign(8, generated_face());
  if (frames.front().empty()) LIPDRIVE_REQUIRE_BUILT(kFixtureDir / "talking_face.avi");
  ASSERT_FALSE(frames.front().empty()) << "no face in the GRID clip or the generated fixture";
  FaceTracker tracker(test::shared_predictor());
  Landmarks2D landmarks;
  ASSERT_EQ(tracker.track(frames[0], landmarks), TrackStatus::kAcquired);

  test::count_allocations_on_this_thread(true);
  const long before_probe = test::allocation_count();
  {
    std::vector<int> probe(3);
    ASSERT_EQ(probe.size(), 3u);
  }
  ASSERT_GT(test::allocation_count(), before_probe) << "the allocation counter does not count";

  for (std::size_t f = 1; f < frames.size(); ++f) {
    const long before = test::allocation_count();
    const TrackStatus status = tracker.track(frames[f], landmarks);
    const bool accepted = tracker.check_fit(landmarks, 0.0);
    const long allocations = test::allocation_count() - before;
    ASSERT_EQ(status, TrackStatus::kTracking) << "frame " << f;
    ASSERT_TRUE(accepted);
    EXPECT_EQ(allocations, 0) << "frame " << f;
  }
}

}  // namespace
}  // namespace lipdrive
