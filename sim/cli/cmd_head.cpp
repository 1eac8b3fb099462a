// `lipdrive-dev head generate`: write the built-in head's pose meshes and landmark map
// (sim/synthetic_head.hpp), the input the build turns into the default models with
// `lipdrive model build`, the same builder as a character's own meshes.
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"
#include "sim/cli/dev_commands.hpp"
#include "sim/synthetic_head.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <memory>

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

void add_head_command(CLI::App& app) {
  auto* head = app.add_subcommand("head", "The built-in synthetic head");
  head->require_subcommand(1);
  auto out = std::make_shared<fs::path>();
  auto* generate = head->add_subcommand(
      "generate", "Write the built-in head: poses161/ and poses17/ (OBJ per pose) and landmarks.toml");
  generate->add_option("--out", *out, "Folder to write into")->required();
  generate->callback([out] { generate_head(*out); });
}

const dev::Registration registration(add_head_command);

}  // namespace
}  // namespace lipdrive
