// `lipdrive-dev expression-fit`: the expression fit (core/fitting.hpp) of a model with
// expression shapes on the landmarks of a `lipdrive process --include-landmarks` table: the
// identity from its first tracked frames (fit_identity, as a calibration's neutral capture),
// then every tracked frame warm-started from the last. Writes frame, height_2d, open, seal and
// one column per expression: the tuning and checking tool of the expression fit.
#include "core/fitting.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/paths.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "sim/cli/dev_commands.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

struct ExpressionFitArgs {
  fs::path model = model_directory() / "ict_face_light.lpm";
  fs::path table, out;
  std::string landmark_set{landmark_set_name(kDefaultLandmarkSet)};
  int neutral_frames = 20;
  FitSettings settings;
};

void run_expression_fit(const ExpressionFitArgs& args) {
  const MorphableModel model = load_model_file(args.model);
  const auto set = parse_landmark_set(args.landmark_set);
  if (!set) throw CommandError(fmt::format("--landmark-set: unknown set {}", args.landmark_set));
  const CsvTable table = read_csv_table(args.table);
  const std::vector<double> tracked = numeric_column(table, "tracked");
  std::vector<std::vector<double>> coordinates;
  for (const char axis : {'x', 'y'})
    for (int i = 0; i < kNumLandmarks; ++i) coordinates.push_back(numeric_column(table, fmt::format("{}{}", axis, i)));
  std::vector<Landmarks2D> frames(tracked.size());
  for (std::size_t row = 0; row < tracked.size(); ++row)
    for (int i = 0; i < kNumLandmarks; ++i)
      frames[row].col(i) << coordinates[i][row], coordinates[kNumLandmarks + i][row];

  std::vector<Landmarks2D> neutral;
  for (std::size_t row = 0; row < tracked.size() && static_cast<int>(neutral.size()) < args.neutral_frames; ++row)
    if (tracked[row] == 1) neutral.push_back(frames[row]);
  if (neutral.empty()) throw CommandError(fmt::format("{}: no tracked frame", args.table.string()), kExitDataError);
  const Eigen::VectorXf identity = fit_identity(model, *set, neutral, args.settings);
  const Fitter fitter(model, *set, args.settings, identity);

  std::ofstream out(args.out);
  if (!out) throw CommandError(fmt::format("{}: cannot write the file", args.out.string()));
  out << "frame,height_2d,open,seal,reprojection_px";
  for (const auto& name : model.expression_names) out << ',' << name;
  out << '\n';
  const std::vector<double> height = numeric_column(table, "height_2d"), open = numeric_column(table, "open"),
                            seal = numeric_column(table, "seal");
  FitOutput fit = Fitter::initial_output();
  for (std::size_t row = 0; row < tracked.size(); ++row) {
    if (tracked[row] != 1) continue;
    fitter.fit(frames[row], fit);
    out << fmt::format("{},{},{},{},{:.3f}", row, height[row], open[row], seal[row], fit.reprojection_error_px);
    for (int e = 0; e < model.num_expressions(); ++e) out << fmt::format(",{:.4f}", fit.expressions[e]);
    out << '\n';
  }
}

void add_expression_fit_command(CLI::App& app) {
  auto args = std::make_shared<ExpressionFitArgs>();
  auto* cmd = app.add_subcommand("expression-fit",
                                 "Fit a model's expression shapes to the landmarks of a `lipdrive process` table");
  cmd->add_option("--model", args->model, "Model with expression shapes")->capture_default_str();
  cmd->add_option("--table", args->table, "CSV of `lipdrive process --include-landmarks`")->required();
  cmd->add_option("--out", args->out, "CSV to write")->required();
  cmd->add_option("--landmark-set", args->landmark_set, "F4 or F5")->capture_default_str();
  cmd->add_option("--neutral-frames", args->neutral_frames, "Tracked frames the identity is fitted on")
      ->capture_default_str();
  cmd->add_option("--lambda", args->settings.lambda, "The identity's regulariser")->capture_default_str();
  cmd->add_option("--sweeps", args->settings.sweeps)->capture_default_str();
  cmd->add_option("--iterations", args->settings.iterations)->capture_default_str();
  cmd->add_option("--expression-prior", args->settings.expression_prior)->capture_default_str();
  cmd->add_option("--jaw-prior-ratio", args->settings.jaw_prior_ratio)->capture_default_str();
  cmd->add_option("--expression-sparsity", args->settings.expression_sparsity)->capture_default_str();
  cmd->add_option("--expression-sigma-mm", args->settings.expression_sigma_mm)->capture_default_str();
  cmd->callback([args] { run_expression_fit(*args); });
}

const dev::Registration registration(add_expression_fit_command);

}  // namespace
}  // namespace lipdrive
