// Per-frame fit time (docs/method.md 3) for the default landmark set F4, 20 and 40 components,
// 1 and 3 iterations, warm-started frame to frame as the pipeline does.
#include "core/fitting.hpp"
#include "firmware_app/config/model_files.hpp"
#include "reference_fitter.hpp"

#include <benchmark/benchmark.h>

#include <algorithm>
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
  const std::filesystem::path path = std::filesystem::path(LIPDRIVE_MODEL_DIR) / "default.lpm";
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
    ->ArgsProduct({{20, 40}, {1, 3}})
    ->Unit(benchmark::kMicrosecond)
    ->Repetitions(9)
    ->ReportAggregatesOnly(true);

}  // namespace
}  // namespace lipdrive
