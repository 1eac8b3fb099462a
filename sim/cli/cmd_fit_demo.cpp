// `lipdrive-dev fit-demo`: the per-frame fitter on the model's own example poses.
// Each pose's landmarks are projected through a fixed camera (optionally with noise),
// fitted from a cold start, and the mouth measures of the fit compared with the truth.
#include "core/fitting.hpp"
#include "core/mouth_measures.hpp"
#include "core/statistics.hpp"
#include "drivers/clock.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/paths.hpp"
#include "sim/cli/dev_commands.hpp"

#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

struct FitDemoArgs {
  std::filesystem::path model = default_model_path();
  std::string landmark_set{landmark_set_name(kDefaultLandmarkSet)};
  double noise_px = 0.0;
};

Eigen::Matrix<double, 3, kNumLandmarks> pose_landmarks(const MorphableModel& model, int pose) {
  const Eigen::VectorXf shape = model.shape(model.pose_coefficients.col(pose));
  Eigen::Matrix<double, 3, kNumLandmarks> points;
  for (int i = 0; i < kNumLandmarks; ++i) {
    const int vertex = model.landmark_vertex[i];
    points.col(i) = vertex < 0 ? Eigen::Vector3d::Constant(std::nan(""))
                               : Eigen::Vector3d(shape.segment<3>(3 * vertex).cast<double>());
  }
  return points;
}

// A head-mounted camera's view: the face turned slightly (yaw 0.15 rad), ~80 px between the
// outer eye corners, image y down, face centred at (320, 240).
Eigen::Matrix<double, 3, 4> demo_camera(const Eigen::Matrix<double, 3, kNumLandmarks>& neutral) {
  const double eye_span_mm = (neutral.col(ibug::kRightEyeOuter) - neutral.col(ibug::kLeftEyeOuter)).norm();
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.15, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Matrix3d flip_y = Eigen::Vector3d(1, -1, 1).asDiagonal();
  Eigen::Matrix<double, 3, 4> camera = Eigen::Matrix<double, 3, 4>::Zero();
  camera.topLeftCorner<2, 3>() = (80.0 / eye_span_mm * flip_y * rotation).topRows<2>();
  camera.col(3) << 320.0, 240.0, 1.0;
  return camera;
}

// The neutral pose and the visemes at full intensity ("<viseme>_100") when the model has
// them, else every pose.
std::vector<int> demo_poses(const MorphableModel& model) {
  std::vector<int> poses;
  for (int p = 0; p < model.num_poses(); ++p) {
    const std::string& name = model.pose_names[p];
    if (name == "neutral" || name.ends_with("_100")) poses.push_back(p);
  }
  if (poses.empty())
    for (int p = 0; p < model.num_poses(); ++p) poses.push_back(p);
  return poses;
}

Landmarks2D with_noise(Landmarks2D landmarks, double sigma_px, std::mt19937& rng) {
  if (sigma_px == 0) return landmarks;
  std::normal_distribution<double> noise(0.0, sigma_px);
  for (double& value : landmarks.reshaped()) value += noise(rng);
  return landmarks;
}

// Median over batches of the time of one fit, in microseconds.
double median_fit_time_us(const Fitter& fitter, const Landmarks2D& landmarks) {
  constexpr int kBatches = 21, kFitsPerBatch = 50;
  std::vector<double> times;
  FitOutput output = Fitter::initial_output();
  for (int batch = 0; batch < kBatches; ++batch) {
    const std::int64_t start = monotonic_ns();
    for (int i = 0; i < kFitsPerBatch; ++i) fitter.fit(landmarks, output);
    times.push_back(ms_since(start) * 1000 / kFitsPerBatch);
  }
  return median(times);
}

void run_fit_demo(const FitDemoArgs& args) {
  const MorphableModel model = load_model_file(args.model);
  if (model.num_poses() == 0)
    throw CommandError(fmt::format("{}: the model has no example poses to fit", args.model.string()), kExitDataError);
  const LandmarkSet set = *parse_landmark_set(args.landmark_set);
  std::unique_ptr<Fitter> fitter;
  try {
    fitter = std::make_unique<Fitter>(model, set);
  } catch (const std::invalid_argument& e) {
    throw CommandError(fmt::format("{}: {}", args.model.string(), e.what()), kExitDataError);
  }

  const Eigen::Matrix<double, 3, 4> camera =
      demo_camera(pose_landmarks(model, model.pose_index("neutral").value_or(0)));
  std::mt19937 rng(1);
  fmt::print("{}: {} poses, fitting {} of {} components{}\n", args.model.string(), model.num_poses(),
             fitter->num_components(), model.num_components(), fitter->truncated_components() ? " (truncated)" : "");
  fmt::print("landmark set {} ({} points), {} px noise, {} iterations, cold start per pose\n\n", args.landmark_set,
             landmark_count(set), args.noise_px, FitSettings{}.iterations);
  fmt::print("{:<12} {:>8} {:>8}   {:>8} {:>8}   {:>8}\n", "pose", "W/d true", "fitted", "H/d true", "fitted",
             "error px");

  std::vector<double> times;
  for (const int pose : demo_poses(model)) {
    const Landmarks2D truth =
        (camera.topLeftCorner<2, 3>() * pose_landmarks(model, pose)).colwise() + camera.topRightCorner<2, 1>();
    const Landmarks2D observed = with_noise(truth, args.noise_px, rng);
    FitOutput fit = Fitter::initial_output();
    fitter->fit(observed, fit);
    const MouthRatios expected = mouth_ratios<2>(truth), fitted = mouth_ratios<2>(fit.projected);
    fmt::print("{:<12} {:>8.3f} {:>8.3f}   {:>8.3f} {:>8.3f}   {:>8.2f}\n", model.pose_names[pose], expected.width,
               fitted.width, expected.height, fitted.height, fit.reprojection_error_px);
    times.push_back(median_fit_time_us(*fitter, observed));
  }
  fmt::print("\nmedian fit time: {:.1f} us per frame\n", median(times));
}

void add_fit_demo_command(CLI::App& app) {
  auto args = std::make_shared<FitDemoArgs>();
  auto* cmd = app.add_subcommand("fit-demo", "Fit the model to its own example poses and compare mouth measures");
  cmd->add_option("--model", args->model, "Model file (.lpm)")->capture_default_str();
  cmd->add_option("--landmark-set", args->landmark_set, "Landmarks to fit (F1 lips ... F5 all 68)")
      ->check(CLI::IsMember(std::vector<std::string>(kLandmarkSetNames.begin(), kLandmarkSetNames.end())))
      ->capture_default_str();
  cmd->add_option("--noise", args->noise_px, "Gaussian noise added to the landmarks, in pixels (fixed seed)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->callback([args] { run_fit_demo(*args); });
}

const dev::Registration registration(add_fit_demo_command);

}  // namespace
}  // namespace lipdrive
