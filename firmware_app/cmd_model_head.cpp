// `lipdrive model generate-head | render`: write the built-in head's pose meshes
// (the input of the default models), and render a pose of a model file to a PNG.
#include "firmware_app/command_error.hpp"
#include "firmware_app/commands.hpp"
#include "firmware_app/model_files.hpp"
#include "firmware_app/paths.hpp"
#include "sim/mesh_renderer.hpp"
#include "sim/synthetic_head.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <opencv2/imgcodecs.hpp>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>
#include <string>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

void make_directory(const fs::path& dir) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw CommandError(fmt::format("{}: cannot create directory: {}", dir.string(), ec.message()));
}

/// DIR/<pose>.obj for every pose.
void write_poses(const fs::path& dir, const SyntheticHead& head) {
  make_directory(dir);
  for (const HeadPose& pose : head.poses) write_obj(dir / (pose.name + ".obj"), Mesh{pose.vertices, head.triangles});
}

void generate_head(const fs::path& out) {
  const SyntheticHead full = generate_synthetic_head(HeadPoseSet::Full161);
  write_poses(out / "poses161", full);
  write_poses(out / "poses17", generate_synthetic_head(HeadPoseSet::FullIntensity17));
  write_landmark_map(out / "landmarks.toml", full.landmark_vertex);  // same mesh, same map for both sets
  spdlog::info("wrote the synthetic head to {}", out.string());
}

struct RenderArgs {
  fs::path model = default_model_path();
  std::string pose = "neutral";
  float yaw_degrees = 0;
  int size = 640;
  fs::path out;
};

void render(const RenderArgs& args) {
  const MorphableModel model = load_model_file(args.model);
  const auto pose = model.pose_index(args.pose);
  if (!pose)
    throw CommandError(fmt::format("{}: no pose \"{}\"; the poses are: {}", args.model.string(), args.pose,
                                   fmt::join(model.pose_names, " ")),
                       kExitDataError);
  const Mesh mesh = model.mesh(model.shape(model.pose_coefficients.col(*pose)));
  const cv::Mat image = render_mesh(mesh, RenderView{args.yaw_degrees, cv::Size(args.size, args.size)});
  bool written = false;
  try {
    written = cv::imwrite(args.out.string(), image);
  } catch (const cv::Exception& e) {
    throw CommandError(fmt::format("{}: cannot write the image: {}", args.out.string(), e.what()));
  }
  if (!written) throw CommandError(fmt::format("{}: cannot write the image", args.out.string()));
}

}  // namespace

void add_model_head_commands(CLI::App& model) {
  auto out = std::make_shared<fs::path>();
  auto* generate = model.add_subcommand(
      "generate-head", "Write the built-in head: poses161/ and poses17/ (OBJ per pose) and landmarks.toml");
  generate->add_option("--out", *out, "Folder to write into")->required();
  generate->callback([out] { generate_head(*out); });

  auto args = std::make_shared<RenderArgs>();
  auto* render_cmd = model.add_subcommand("render", "Render one pose of a model file to a PNG");
  render_cmd->add_option("--model", args->model, "Model file (.lpm)")->capture_default_str();
  render_cmd->add_option("--pose", args->pose, "Pose name (see `lipdrive model info`)")->capture_default_str();
  render_cmd->add_option("--yaw", args->yaw_degrees, "Head rotation in degrees: 0 frontal, 90 right profile")
      ->capture_default_str();
  render_cmd->add_option("--size", args->size, "Image width and height in pixels")
      ->check(CLI::Range(16, 8192))
      ->capture_default_str();
  render_cmd->add_option("--out", args->out, "PNG file to write")->required();
  render_cmd->callback([args] { render(*args); });
}

}  // namespace lipdrive
