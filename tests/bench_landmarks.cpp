// Landmarks side by side (issue: the ERT against dlib's own): lipdrive's ShapePredictor on
// the compact file the build converts, and dlib::shape_predictor on Debian's .dat, on the same
// 640x480 frames of the generated talking face and the same face boxes (the first detected,
// then each frame's box from the previous frame's landmarks, as the tracker does). Each
// iteration runs both on one frame, alternating which goes first, so load on a shared machine
// falls on both alike. Counters: per-call median and p99 of each (µs, core/statistics' nearest
// rank), their ratio, and the mean landmark difference in inter-ocular distances (ours
// rounded as dlib rounds).
#include "core/face_tracker.hpp"  // interocular_distance
#include "core/landmarks.hpp"
#include "core/shape_predictor.hpp"
#include "core/statistics.hpp"
#include "firmware_app/config/paths.hpp"
#include "fixture_paths.hpp"
#include "shared_predictor.hpp"

#include <benchmark/benchmark.h>
#include <dlib/image_processing.h>
#include <dlib/opencv/cv_image.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <chrono>
#include <filesystem>
#include <numbers>
#include <thread>
#include <vector>

namespace lipdrive {
namespace {

struct Frames {
  std::vector<cv::Mat> gray;
  std::vector<FaceBox> boxes;
};

const Frames& frames() {
  static const Frames clip = [] {
    Frames f;
    cv::VideoCapture capture(test::kClip.string());
    cv::Mat bgr;
    ShapePredictor predictor(test::shared_predictor());
    FaceDetector detector = test::shared_predictor()->detector();
    Landmarks2D landmarks;
    while (capture.read(bgr)) {
      cv::Mat gray;
      cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
      if (f.boxes.empty()) {
        const auto faces = detector.detect(gray);
        if (faces.empty()) continue;
        f.boxes.push_back(faces.front());
      } else {
        f.boxes.push_back(test::shared_predictor()->box_for(landmarks, std::numbers::pi));
      }
      f.boxes.back().roll = 0;  // upright, as dlib's predictor takes them
      predictor.predict(gray, f.boxes.back(), landmarks);
      f.gray.push_back(gray);
    }
    return f;
  }();
  return clip;
}

void BM_LandmarksAgainstDlib(benchmark::State& state) {
  if (!std::filesystem::exists(kDebianPredictorPath) || !std::filesystem::exists(test::kClip)) {
    state.SkipWithError("needs Debian's dlib predictor and the generated clip");
    return;
  }
  const Frames& clip = frames();
  if (clip.gray.empty()) {
    state.SkipWithError("no face in the generated clip");
    return;
  }
  dlib::shape_predictor theirs;
  dlib::deserialize(kDebianPredictorPath) >> theirs;
  ShapePredictor ours(test::shared_predictor());
  Landmarks2D landmarks;
  std::vector<double> ours_us, theirs_us;
  ours_us.reserve(static_cast<std::size_t>(state.max_iterations));
  theirs_us.reserve(static_cast<std::size_t>(state.max_iterations));
  double difference_sum = 0;
  std::size_t frame = 0;
  bool ours_first = true;
  for (auto _ : state) {
    const cv::Mat& gray = clip.gray[frame];
    const FaceBox& box = clip.boxes[frame];
    const auto run_ours = [&] {
      const auto start = std::chrono::steady_clock::now();
      ours.predict(gray, box, landmarks);
      benchmark::DoNotOptimize(landmarks);
      ours_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count());
    };
    dlib::full_object_detection detection;
    const auto run_theirs = [&] {
      const auto start = std::chrono::steady_clock::now();
      detection = theirs(dlib::cv_image<unsigned char>(gray), dlib::rectangle(box.left, box.top, box.right, box.bottom));
      theirs_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count());
    };
    if (ours_first) {
      run_ours();
      run_theirs();
    } else {
      run_theirs();
      run_ours();
    }
    Landmarks2D dlib_points;
    for (int i = 0; i < kNumLandmarks; ++i) dlib_points.col(i) << detection.part(i).x(), detection.part(i).y();
    const Landmarks2D rounded = (landmarks.array() + 0.5).floor();
    difference_sum += (rounded - dlib_points).colwise().norm().mean() / interocular_distance(dlib_points);
    ours_first = !ours_first;
    frame = (frame + 1) % clip.gray.size();
  }
  state.counters["lipdrive_median_us"] = median(ours_us);
  state.counters["lipdrive_p99_us"] = quantile(ours_us, 0.99);
  state.counters["dlib_median_us"] = median(theirs_us);
  state.counters["dlib_p99_us"] = quantile(theirs_us, 0.99);
  state.counters["dlib_over_lipdrive"] = median(theirs_us) / median(ours_us);
  state.counters["mean_difference_iod"] = difference_sum / static_cast<double>(state.iterations());
}

BENCHMARK(BM_LandmarksAgainstDlib)->Unit(benchmark::kMicrosecond)->MinTime(2.0)->Repetitions(3);

// Ours alone, each frame after a pause of the first argument in µs: 0 is back to back, as
// `lipdrive process` runs; 16667 is a 60 fps camera's period, as the daemon runs. The
// difference is what the frame costs when the machine has done other things (or nothing)
// since the last one: on a shared VM the predictor's ~4 MB per frame come from further away.
// Second argument 1: ShapePredictor::warm() 2 ms before the frame, as the daemon's default
// `[scheduling] warm_ahead_us = 2000` does.
void BM_LandmarksPaced(benchmark::State& state) {
  if (!std::filesystem::exists(test::kClip)) {
    state.SkipWithError("needs the generated clip");
    return;
  }
  const Frames& clip = frames();
  if (clip.gray.empty()) {
    state.SkipWithError("no face in the generated clip");
    return;
  }
  ShapePredictor ours(test::shared_predictor());
  Landmarks2D landmarks;
  std::vector<double> us, warm_us;
  us.reserve(static_cast<std::size_t>(state.max_iterations));
  warm_us.reserve(static_cast<std::size_t>(state.max_iterations));
  const auto pause = std::chrono::microseconds(state.range(0));
  constexpr auto kWarmAhead = std::chrono::microseconds(2000);
  std::size_t frame = 0;
  for (auto _ : state) {
    if (state.range(1) == 0) {
      std::this_thread::sleep_for(pause);
    } else {
      std::this_thread::sleep_for(pause - kWarmAhead);
      const auto warm_start = std::chrono::steady_clock::now();
      ours.warm();
      warm_us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - warm_start).count());
      std::this_thread::sleep_for(kWarmAhead);
    }
    const auto start = std::chrono::steady_clock::now();
    ours.predict(clip.gray[frame], clip.boxes[frame], landmarks);
    benchmark::DoNotOptimize(landmarks);
    us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count());
    frame = (frame + 1) % clip.gray.size();
  }
  state.counters["median_us"] = median(us);
  state.counters["p99_us"] = quantile(us, 0.99);
  if (!warm_us.empty()) state.counters["warm_median_us"] = median(warm_us);
}

BENCHMARK(BM_LandmarksPaced)->Args({0, 0})->Args({16667, 0})->Args({16667, 1})->Unit(benchmark::kMicrosecond)->Iterations(300)->Repetitions(2);

}  // namespace
}  // namespace lipdrive
