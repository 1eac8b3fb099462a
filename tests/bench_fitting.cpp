// Per-frame fit time (docs/method.md 3) for the default landmark set F4, 20 and 40 components,
// 1, 3 and 10 (the default) iterations, warm-started frame to frame as the pipeline does; the ICT head's
// expression fit; the viseme weights of a fitted frame.
#include "build_paths.hpp"
#include "core/fitting.hpp"
#include "core/statistics.hpp"
#include "core/viseme_weights.hpp"
#include "firmware_app/config/model_files.hpp"
#include "reference_fitter.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <random>
#include <utility>
#include <vector>

namespace lipdrive {
namespace {

// The default model (if built) when it fills the compiled size `components` of the fitter
// (20 or 40; fewer components are zero-padded to it), else a random model of that size:
// the fit's cost depends only on the compiled size.
MorphableModel bench_model(int components) {
  const std::filesystem::path path = std::filesystem::path(test::kModelDir) / "default.lpm";
  if (std::filesystem::exists(path)) {
    MorphableModel model = load_model_file(path);
    const int used = std::min(model.num_components(), components);
    if (used > components - 20) return testing::truncated(std::move(model), used);
  }
  return testing::random_model(3000, components, 1);
}

// Frames cycling through the model's example poses (random shapes for a random model),
// seen through a camera with ~80 px between the outer eye corners, with 1 px noise.
std::vector<Landmarks2D> bench_frames(const MorphableModel& model) {
  const auto eyes = testing::model_landmarks(model, Eigen::VectorXd::Zero(1));
  const double eye_span_mm = (eyes.col(ibug::kRightEyeOuter) - eyes.col(ibug::kLeftEyeOuter)).norm();
  const Eigen::Matrix<double, 3, 4> camera = testing::test_camera(80.0 / eye_span_mm);
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Landmarks2D> frames;
  for (int frame = 0; frame < 64; ++frame) {
    const Eigen::VectorXd alpha =
        model.num_poses() > 0 ? Eigen::VectorXd(model.pose_coefficients.col(frame % model.num_poses()).cast<double>())
                              : Eigen::VectorXd(testing::random_coefficients(model.num_components(), frame));
    Landmarks2D landmarks = testing::project(camera, testing::model_landmarks(model, alpha));
    for (double& value : landmarks.reshaped()) value += noise(rng);
    frames.push_back(landmarks);
  }
  return frames;
}

void BM_FitF4(benchmark::State& state) {
  const int components = static_cast<int>(state.range(0));
  const int iterations = static_cast<int>(state.range(1));
  const MorphableModel model = bench_model(components);
  state.SetLabel(model.num_poses() > 0 ? "default model" : "random model");
  const Fitter fitter(model, LandmarkSet::F4, {.iterations = iterations});
  const std::vector<Landmarks2D> frames = bench_frames(model);
  FitOutput output = Fitter::initial_output();
  double error_sum = 0;
  std::size_t frame = 0;
  for (auto _ : state) {
    fitter.fit(frames[frame], output);
    benchmark::DoNotOptimize(output);
    error_sum += output.reprojection_error_px;
    frame = (frame + 1) % frames.size();
  }
  state.counters["reprojection_px"] = error_sum / static_cast<double>(state.iterations());
}

BENCHMARK(BM_FitF4)
    ->ArgNames({"K", "iterations"})
    ->ArgsProduct({{20, 40}, {1, 3, 10}})
    ->Unit(benchmark::kMicrosecond)
    ->Repetitions(9)
    ->ReportAggregatesOnly(true);

// The ICT head's expression fit (53 shapes, the mean identity), landmark set F4 (arg 3) or F5
// (arg 4): frames of random expressions (each shape at a random weight with probability 0.25)
// with 1 px noise, ~80 px between the outer eye corners, warm-started frame to frame.
void BM_FitIct(benchmark::State& state) {
  const MorphableModel model = load_model_file(std::filesystem::path(test::kModelDir) / "ict_face_light.lpm");
  const LandmarkSet set = static_cast<LandmarkSet>(state.range(0));
  const Fitter fitter(model, set);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uniform(0.f, 1.f);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Landmarks2D> frames;
  const Eigen::Matrix3Xf neutral = Eigen::Map<const Eigen::Matrix3Xf>(model.mean.data(), 3, model.num_vertices());
  const double eye_span_mm = (neutral.col(model.landmark_vertex[ibug::kRightEyeOuter]) -
                              neutral.col(model.landmark_vertex[ibug::kLeftEyeOuter]))
                                 .norm();
  const Eigen::Matrix<double, 3, 4> camera = testing::test_camera(80.0 / eye_span_mm);
  for (int frame = 0; frame < 64; ++frame) {
    Eigen::VectorXf w = Eigen::VectorXf::Zero(model.num_expressions());
    for (float& weight : w)
      if (uniform(rng) < 0.25f) weight = uniform(rng);
    const Eigen::VectorXf shape = model.mean + model.expressions * w;
    Eigen::Matrix<double, 3, kNumLandmarks> points;
    for (int i = 0; i < kNumLandmarks; ++i)
      points.col(i) = shape.segment<3>(3 * model.landmark_vertex[i]).cast<double>();
    Landmarks2D landmarks = testing::project(camera, points);
    for (double& value : landmarks.reshaped()) value += noise(rng);
    frames.push_back(landmarks);
  }
  FitOutput output = Fitter::initial_output();
  // The weights leave above a performer's rest point (core/fitting.hpp above_rest), part of the cost.
  const FitOutput::Expressions rest = FitOutput::Expressions::Constant(0.1);
  FitOutput::Expressions relative;
  std::vector<double> us;
  us.reserve(static_cast<std::size_t>(state.max_iterations));
  std::size_t frame = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    fitter.fit(frames[frame], output);
    above_rest(output.expressions, rest, relative);
    benchmark::DoNotOptimize(output);
    benchmark::DoNotOptimize(relative);
    us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count());
    frame = (frame + 1) % frames.size();
  }
  // Per call, core/statistics' nearest rank: the figures a per-frame budget is stated in.
  state.counters["median_us"] = median(us);
  state.counters["p99_us"] = quantile(us, 0.99);
}

BENCHMARK(BM_FitIct)
    ->ArgName("set")
    ->Arg(static_cast<int>(LandmarkSet::F4))
    ->Arg(static_cast<int>(LandmarkSet::F5))
    ->Unit(benchmark::kMicrosecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true);

// The measures stage's viseme weights on the default model (its 161 example poses matched in
// the image over F4, then the NNLS), on fitted frames cycling through the poses. Per call,
// core/statistics' nearest rank.
void BM_VisemePoseMatch(benchmark::State& state) {
  const std::filesystem::path path = std::filesystem::path(test::kModelDir) / "default.lpm";
  if (!std::filesystem::exists(path)) {
    state.SkipWithError("the default model is not built");
    return;
  }
  const MorphableModel model = load_model_file(path);
  const VisemeSolver solver(model, LandmarkSet::F4);
  const Fitter fitter(model, LandmarkSet::F4);
  const std::vector<Landmarks2D> frames = bench_frames(model);
  std::vector<FitOutput> fits;
  FitOutput output = Fitter::initial_output();
  for (const Landmarks2D& frame : frames) {
    fitter.fit(frame, output);
    fits.push_back(output);
  }
  std::vector<double> us;
  us.reserve(static_cast<std::size_t>(state.max_iterations));
  std::size_t frame = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(solver.solve(fits[frame], frames[frame]));
    us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count());
    frame = (frame + 1) % frames.size();
  }
  state.counters["median_us"] = median(us);
  state.counters["p99_us"] = quantile(us, 0.99);
}

BENCHMARK(BM_VisemePoseMatch)->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

// The measures stage's viseme weights on a model with expression shapes (the ICT head): the
// table over the frame's 52 ARKit weights, then the seal. The work does not depend on the
// values: random ARKit weights and seals, cycled. Per call, core/statistics' nearest rank.
void BM_VisemesFromArkit(benchmark::State& state) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> unit(0, 1);
  std::vector<std::pair<ArkitWeights, double>> frames(256);
  for (auto& [arkit, seal] : frames) {
    for (float& w : arkit) w = 0.5f * unit(rng);
    seal = unit(rng);
  }
  std::vector<double> us;
  us.reserve(static_cast<std::size_t>(state.max_iterations));
  std::size_t frame = 0;
  for (auto _ : state) {
    const auto start = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(visemes_from_arkit(frames[frame].first, frames[frame].second));
    us.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count());
    frame = (frame + 1) % frames.size();
  }
  state.counters["median_us"] = median(us);
  state.counters["p99_us"] = quantile(us, 0.99);
}

BENCHMARK(BM_VisemesFromArkit)->Unit(benchmark::kMicrosecond)->Repetitions(5)->ReportAggregatesOnly(true);

}  // namespace
}  // namespace lipdrive
