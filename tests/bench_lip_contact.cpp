// Per-frame cost of what validates a tracked face and measures lip contact (docs/method.md 1
// and 9) on the generated 640x480 talking face, at each frame's tracked landmarks:
// FaceAppearance::compare, measure_lip_gap + seal_probability + fused_opening, and both
// together (what a tracked frame adds on the processing thread). Besides Google Benchmark's
// mean, every run reports the median and p99 of the single calls (counters median_us,
// p99_us; core/statistics' nearest rank), the figures a per-frame budget is stated in. They
// are the calling thread's CPU time, so that other processes on a shared machine do not
// count as the code's cost.
#include "core/face_check.hpp"
#include "core/face_tracker.hpp"
#include "core/lip_contact.hpp"
#include "core/mouth_measures.hpp"
#include "core/statistics.hpp"
#include "fixture_paths.hpp"
#include "shared_predictor.hpp"

#include <benchmark/benchmark.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <ctime>
#include <vector>

namespace lipdrive {
namespace {

struct TrackedFrames {
  std::vector<cv::Mat> frames;  // luma, 640x480
  std::vector<Landmarks2D> landmarks;
  std::vector<double> heights;  // landmark inner-lip height H/d
  FaceAppearance face;          // captured on the first frame, as at acquisition
};

const TrackedFrames& tracked_frames() {
  static const TrackedFrames clip = [] {
    TrackedFrames c;
    FaceTracker tracker(test::shared_predictor());
    cv::VideoCapture capture(test::kClip.string());
    cv::Mat bgr, gray;
    Landmarks2D landmarks;
    while (capture.read(bgr) && c.frames.size() < 100) {
      cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
      if (tracker.track(gray, landmarks) == TrackStatus::kNoFace) continue;
      if (c.frames.empty()) c.face.capture(gray, landmarks);
      c.frames.push_back(gray.clone());
      c.landmarks.push_back(landmarks);
      c.heights.push_back(mouth_ratios<2>(landmarks).height);
    }
    return c;
  }();
  return clip;
}

double thread_cpu_us() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e6 + static_cast<double>(t.tv_nsec) / 1e3;
}

// Runs `call(frame)` once per iteration over the clip's frames, timing each call, and sets
// the counters median_us and p99_us.
template <typename Call>
void timed_per_frame(benchmark::State& state, Call call) {
  const TrackedFrames& clip = tracked_frames();
  if (clip.frames.empty()) return state.SkipWithError("the generated clip is not tracked");
  state.SetLabel(std::to_string(clip.frames.front().cols) + "x" + std::to_string(clip.frames.front().rows));
  std::vector<double> us;
  us.reserve(static_cast<std::size_t>(state.max_iterations));
  std::size_t f = 0;
  for (auto _ : state) {
    const double start = thread_cpu_us();
    call(clip, f);
    us.push_back(thread_cpu_us() - start);
    f = (f + 1) % clip.frames.size();
  }
  state.counters["median_us"] = median(us);
  state.counters["p99_us"] = quantile(us, 0.99);
}

void compare_face(const TrackedFrames& clip, std::size_t f) {
  benchmark::DoNotOptimize(clip.face.compare(clip.frames[f], clip.landmarks[f]));
}

void lip_contact(const TrackedFrames& clip, std::size_t f) {
  const LipGap gap = measure_lip_gap(clip.frames[f], cv::Mat(), clip.landmarks[f]);
  const double seal = seal_probability(gap, clip.heights[f]);
  benchmark::DoNotOptimize(fused_opening(clip.heights[f], seal));
}

void BM_FaceAppearanceCompare(benchmark::State& state) { timed_per_frame(state, compare_face); }
void BM_LipContact(benchmark::State& state) { timed_per_frame(state, lip_contact); }
void BM_AddedPerTrackedFrame(benchmark::State& state) {
  timed_per_frame(state, [](const TrackedFrames& clip, std::size_t f) {
    compare_face(clip, f);
    lip_contact(clip, f);
  });
}

BENCHMARK(BM_FaceAppearanceCompare)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_LipContact)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_AddedPerTrackedFrame)->Unit(benchmark::kMicrosecond);

}  // namespace
}  // namespace lipdrive
