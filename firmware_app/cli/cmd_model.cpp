// `lipdrive model build | info | render`: build a morphable model from a folder of pose
// meshes, describe a model file, and render one of its poses, or the head fitted to a frame of
// a video beside that frame, to a PNG.
#include "core/model_builder.hpp"
#include "core/model_format.hpp"
#include "drivers/image_codec.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/cli/options.hpp"
#include "firmware_app/cli/recording.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/paths.hpp"
#include "firmware_app/config/predictor_file.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "sim/mesh_renderer.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

// The pose meshes of a folder: *.obj sorted by name, "neutral.obj" first so the
// first pose (and the reference for vertex order) is the rest pose when there is one.
std::vector<fs::path> pose_files(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw CommandError(fmt::format("{}: {}", dir.string(),
                                   fs::exists(dir, ec) ? "a file, not a folder of pose meshes" : "no such directory"),
                       kExitNoInput);
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.is_regular_file() && entry.path().extension() == ".obj") files.push_back(entry.path());
  if (files.size() < 2)
    throw CommandError(
        fmt::format("{}: found {} .obj files, a model needs at least 2 poses", dir.string(), files.size()),
        kExitNoInput);
  std::sort(files.begin(), files.end(), [](const fs::path& a, const fs::path& b) {
    const bool a_neutral = a.filename() == "neutral.obj", b_neutral = b.filename() == "neutral.obj";
    if (a_neutral != b_neutral) return a_neutral;
    return a.filename() < b.filename();
  });
  return files;
}

std::string one_based(const Triangle& t) { return fmt::format("{} {} {}", t[0] + 1, t[1] + 1, t[2] + 1); }

// Every pose must share the reference's vertex order: PCA over meshes whose
// vertices do not correspond would model the numbering, not the face.
void check_same_topology(const fs::path& file, const Mesh& mesh, const fs::path& reference_file,
                         const Mesh& reference) {
  if (mesh.vertices.cols() != reference.vertices.cols())
    throw CommandError(fmt::format("{}: {} vertices, but {} has {}", file.string(), mesh.vertices.cols(),
                                   reference_file.filename().string(), reference.vertices.cols()),
                       kExitDataError);
  if (mesh.triangles.size() != reference.triangles.size())
    throw CommandError(fmt::format("{}: {} triangles, but {} has {}", file.string(), mesh.triangles.size(),
                                   reference_file.filename().string(), reference.triangles.size()),
                       kExitDataError);
  const auto [differs, _] = std::mismatch(mesh.triangles.begin(), mesh.triangles.end(), reference.triangles.begin());
  if (differs != mesh.triangles.end()) {
    const auto t = differs - mesh.triangles.begin();
    throw CommandError(
        fmt::format("{}: triangle list differs from {} at face {} ({} vs {}, 1-based vertices)", file.string(),
                    reference_file.filename().string(), t + 1, one_based(*differs), one_based(reference.triangles[t])),
        kExitDataError);
  }
}

void check_landmarks_in_range(const fs::path& map_file, const std::array<std::int32_t, kNumLandmarks>& map,
                              Eigen::Index vertex_count) {
  for (int l = 0; l < kNumLandmarks; ++l)
    if (map[l] >= vertex_count)
      throw CommandError(fmt::format("{}: landmarks.{}: vertex {} outside the meshes' 0..{}", map_file.string(), l,
                                     map[l], vertex_count - 1),
                         kExitDataError);
}

// Fraction of the total variance held by each kept component.
Eigen::VectorXd variance_fractions(const MorphableModel& model) {
  return model.stddev.cast<double>().array().square() / double(model.total_variance);
}

struct BuildArgs {
  fs::path poses, landmarks, out;
  ModelBuildOptions options;
};

void run_build(const BuildArgs& args) {
  ModelBuildInput input;
  input.landmark_vertex = read_landmark_map(args.landmarks);
  const auto files = pose_files(args.poses);
  Mesh reference;
  for (const auto& file : files) {
    Mesh mesh = read_obj(file);
    if (input.pose_vertices.empty()) {
      reference = mesh;
      input.triangles = mesh.triangles;
    } else {
      check_same_topology(file, mesh, files.front(), reference);
    }
    input.pose_names.push_back(file.stem().string());
    input.pose_vertices.push_back(std::move(mesh.vertices));
  }
  check_landmarks_in_range(args.landmarks, input.landmark_vertex, reference.vertices.cols());

  MorphableModel model;
  try {
    model = build_model(input, args.options);
  } catch (const ModelBuildError& e) {
    throw CommandError(fmt::format("{}: {}", args.poses.string(), e.what()), kExitDataError);
  }
  save_model_file(args.out, model);
  fmt::print("{}: {} poses, {} vertices, {} components, {:.2f} % of the variance kept\n", args.out.string(),
             model.num_poses(), model.num_vertices(), model.num_components(), 100 * variance_fractions(model).sum());
}

void print_info(const fs::path& file) {
  const MorphableModel model = load_model_file(file);
  fmt::print("file:           {}\n", file.string());
  fmt::print("format version: {}\n", model_format_version(model));
  fmt::print("vertices:       {}\n", model.num_vertices());
  fmt::print("triangles:      {}\n", model.triangles.size());
  fmt::print("components:     {}{}\n", model.num_components(), model.has_expressions() ? " (identity)" : "");
  fmt::print("poses:          {}\n", model.num_poses());
  if (model.has_expressions())
    fmt::print("expressions:    {}: {}\n", model.num_expressions(), fmt::join(model.expression_names, " "));

  const Eigen::VectorXd fractions = variance_fractions(model);
  fmt::print("\n{:>9}  {:>10}  {:>12}\n", "component", "variance %", "cumulative %");
  double cumulative = 0;
  for (Eigen::Index k = 0; k < fractions.size(); ++k) {
    cumulative += fractions[k];
    fmt::print("{:>9}  {:>10.3f}  {:>12.3f}\n", k, 100 * fractions[k], 100 * cumulative);
  }
  fmt::print("\n");
  for (double target : {0.90, 0.95, 0.99}) {
    double sum = 0;
    Eigen::Index k = 0;
    while (k < fractions.size() && sum < target) sum += fractions[k++];
    if (sum >= target)
      fmt::print("{:.0f} % of the variance: {} component{}\n", 100 * target, k, k == 1 ? "" : "s");
    else
      fmt::print("{:.0f} % of the variance: not reached (all {} components hold {:.2f} %)\n", 100 * target, k,
                 100 * sum);
  }

  std::vector<int> unmapped;
  for (int l = 0; l < kNumLandmarks; ++l)
    if (model.landmark_vertex[l] < 0) unmapped.push_back(l);
  fmt::print("landmarks: {}/{} mapped\n", model.mapped_landmark_count(), kNumLandmarks);
  if (!unmapped.empty()) fmt::print("unmapped:  {}\n", fmt::join(unmapped, " "));
}

struct RenderArgs {
  fs::path model = default_model_path();
  std::string pose = "neutral";
  float yaw_degrees = 0;
  int size = 640;
  fs::path video;  // given: the head fitted to its frame `frame`, beside that frame
  int frame = 0;
  fs::path out;
};

// The shape of a pose name: an example pose, or for a model with expression shapes "neutral"
// (the mean) or an expression at full weight.
Eigen::VectorXf named_shape(const MorphableModel& model, const std::string& name, const fs::path& file) {
  if (const auto pose = model.pose_index(name)) return model.shape(model.pose_coefficients.col(*pose));
  if (model.has_expressions()) {
    if (name == "neutral") return model.mean;
    if (const auto expression = model.expression_index(name)) return model.mean + model.expressions.col(*expression);
    throw CommandError(fmt::format("{}: no pose \"{}\"; the poses are: neutral {}", file.string(), name,
                                   fmt::join(model.expression_names, " ")),
                       kExitDataError);
  }
  throw CommandError(
      fmt::format("{}: no pose \"{}\"; the poses are: {}", file.string(), name, fmt::join(model.pose_names, " ")),
      kExitDataError);
}

/// One frame of a video and what the daemon's processing made of it, tracked and fitted from the
/// video's first frame on as `lipdrive process` does (the default configuration on --model).
struct FittedFrame {
  cv::Mat gray;
  Landmarks2D landmarks;
  Eigen::Matrix<double, 3, 4> camera;
  Eigen::VectorXf shape;  // the fitted head's shape vector
};

FittedFrame fit_frame(const MorphableModel& model, const RenderArgs& args) {
  SimulatedCamera video = open_recording(args.video);
  Config config;
  config.model.file = args.model;
  if (video.independent_frames()) config.tracker.settings.still_cascade = load_still_cascade();
  const std::unique_ptr<FrameProcessor> processor = make_processor(config, load_performer(config));
  fit_take_identity(args.video, Rotation::k0, *processor);
  const std::string name = args.video.string();
  Frame frame;
  const FrameMeasurement* result = nullptr;
  Eigen::VectorXf identity;  // the one the frame is fitted on
  for (int n = 0; n <= args.frame; ++n) {
    const GrabStatus status = video.grab(frame, std::chrono::milliseconds(0));
    if (status == GrabStatus::kEndOfStream)
      throw CommandError(fmt::format("{}: {} frames, no frame {}", name, n, args.frame), kExitDataError);
    if (status != GrabStatus::kFrame)
      throw CommandError(fmt::format("{}: frame {}: {}", name, n, video.last_error().value_or("not decoded")),
                         kExitDataError);
    if (video.independent_frames()) processor->forget(FaceTracker::Next::kStill);
    identity = processor->identity();
    result = &processor->process(frame.gray, frame.cr);
  }
  if (!result->tracked)
    throw CommandError(fmt::format("{}: frame {}: no face tracked", name, args.frame), kExitDataError);
  if (processor->identity_pending())
    fmt::print(stderr,
               "frame {}: fitted before the identity of the first tracked frames ([model] "
               "auto_identity_frames)\n",
               args.frame);
  const FitOutput& fit = processor->fit();
  fmt::print(stderr, "frame {}: fit quality {:.3f}, reprojection error {:.2f} px\n", args.frame,
             result->measures.quality, fit.reprojection_error_px);
  FittedFrame fitted{frame.gray.clone(), result->landmarks, fit.camera, {}};
  if (model.has_expressions()) {
    fitted.shape = model.shape(identity.size() ? identity : Eigen::VectorXf::Zero(model.num_components()),
                               fit.expressions.head(model.num_expressions()).cast<float>());
  } else {
    fitted.shape = model.shape(fit.coefficients.head(model.num_components()).cast<float>());
  }
  return fitted;
}

/// The frame around its tracked landmarks with them drawn, beside the fitted head rendered
/// through the fit's camera (camera_projection) into the same crop: `height` pixels high.
cv::Mat frame_beside_head(const FittedFrame& fitted, const MorphableModel& model, int height) {
  const Eigen::Vector2d lo = fitted.landmarks.rowwise().minCoeff(), hi = fitted.landmarks.rowwise().maxCoeff();
  const Eigen::Vector2d margin = 0.3 * (hi - lo);
  const cv::Rect face =
      cv::Rect(cv::Point(static_cast<int>(lo.x() - margin.x()), static_cast<int>(lo.y() - 2 * margin.y())),
               cv::Point(static_cast<int>(hi.x() + margin.x()), static_cast<int>(hi.y() + margin.y()))) &
      cv::Rect(0, 0, fitted.gray.cols, fitted.gray.rows);
  if (face.width < 2 || face.height < 2) throw CommandError("the tracked face lies outside the frame", kExitDataError);
  const double zoom = static_cast<double>(height) / face.height;
  const cv::Size size(static_cast<int>(std::lround(face.width * zoom)), height);

  cv::Mat left;
  cv::resize(fitted.gray(face), left, size, 0, 0, cv::INTER_CUBIC);
  cv::cvtColor(left, left, cv::COLOR_GRAY2BGR);
  for (int l = 0; l < kNumLandmarks; ++l) {
    const Eigen::Vector2d p = zoom * (fitted.landmarks.col(l) - Eigen::Vector2d(face.x, face.y));
    cv::circle(left, cv::Point2d(p.x(), p.y()), std::max(1, height / 200), cv::Scalar(80, 220, 80), cv::FILLED,
               cv::LINE_AA);
  }
  ImageProjection projection = camera_projection(fitted.camera);
  projection.scale *= static_cast<float>(zoom);
  projection.offset = (zoom * (projection.offset.cast<double>() - Eigen::Vector2d(face.x, face.y))).cast<float>();
  cv::Mat both;
  cv::hconcat(left, render_mesh(model.mesh(fitted.shape), size, projection), both);
  return both;
}

void render(const RenderArgs& args) {
  const MorphableModel model = load_model_file(args.model);
  const cv::Mat image = args.video.empty() ? render_mesh(model.mesh(named_shape(model, args.pose, args.model)),
                                                         RenderView{args.yaw_degrees, cv::Size(args.size, args.size)})
                                           : frame_beside_head(fit_frame(model, args), model, args.size);
  try {
    write_png(args.out, image);
  } catch (const MediaError& e) {
    throw CommandError(e.what());
  }
}

void add_build_command(CLI::App& model) {
  auto args = std::make_shared<BuildArgs>();
  auto* cmd = model.add_subcommand("build", "Build a morphable model (PCA) from a folder of pose meshes");
  cmd->add_option("--poses", args->poses, "Folder of OBJ meshes with identical vertex order, one per pose")->required();
  cmd->add_option("--landmarks", args->landmarks, "Landmark map (TOML: [landmarks] iBUG index = vertex)")->required();
  cmd->add_option("--out", args->out, "Model file to write (.lpm)")->required();
  cmd->add_option("--components", args->options.components,
                  "Number of components to keep (0 = smallest count reaching --variance)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--variance", args->options.variance_target,
                  "Fraction of the variance to keep when --components is 0")
      // build_model's range, (0, 1]: none of the variance keeps no component.
      ->check(CLI::Validator(
          [](std::string& value) {
            double fraction = 0;
            return CLI::detail::lexical_cast(value, fraction) && fraction > 0 && fraction <= 1
                       ? std::string()
                       : "must be more than 0 and at most 1, got " + value;
          },
          "FLOAT in (0 - 1]"))
      ->capture_default_str();
  cmd->callback([args, cmd] {
    refuse_out_over_input(*cmd);
    run_build(*args);
  });
}

void add_info_command(CLI::App& model) {
  auto file = std::make_shared<fs::path>(default_model_path());
  auto* cmd = model.add_subcommand("info", "Describe a model file: sizes, variance per component, landmarks");
  cmd->add_option("file", *file, "Model file (.lpm)")->capture_default_str();
  cmd->callback([file] { print_info(*file); });
}

void add_render_command(CLI::App& model) {
  auto args = std::make_shared<RenderArgs>();
  auto* cmd = model.add_subcommand(
      "render", "Render one pose of a model file, or the head it fits to a video frame beside that frame, to a PNG");
  cmd->add_option("--model", args->model, "Model file (.lpm)")->capture_default_str();
  cmd->add_option("--pose", args->pose,
                  "Pose name (see `lipdrive model info`); for a model with expressions also an expression")
      ->capture_default_str();
  cmd->add_option("--yaw", args->yaw_degrees, "Head rotation in degrees: 0 frontal, 90 right profile")
      ->check(finite_range(-180.0, 180.0))
      ->capture_default_str();
  cmd->add_option("--size", args->size, "Image width and height in pixels (with --video: the height)")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  cmd->add_option("--video", args->video,
                  "A recording: render the head fitted to its frame --frame (tracked from the first frame on, as "
                  "`lipdrive process` does) beside that frame and its landmarks, through the fit's camera");
  cmd->add_option("--frame", args->frame, "With --video: the frame, counted from 0")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd->add_option("--out", args->out, "PNG file to write")->required();
  cmd->callback([args, cmd] {
    refuse_out_over_input(*cmd);
    render(*args);
  });
}

}  // namespace

void add_model_command(CLI::App& app) {
  auto* model = app.add_subcommand("model", "Build, inspect and render morphable models");
  model->require_subcommand(1);
  add_build_command(*model);
  add_info_command(*model);
  add_render_command(*model);
}

}  // namespace lipdrive
