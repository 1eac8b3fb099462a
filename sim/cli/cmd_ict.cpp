// `lipdrive-dev ict import`: converts the ICT Face Model Light into a model file
// (sim/ict_import.hpp, docs/ict-model.md). The build does not run it: its output,
// models/ict_face_light.lpm, is committed, and this command reproduces it.
#include "core/model_format.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"
#include "sim/cli/dev_commands.hpp"
#include "sim/ict_import.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <filesystem>
#include <memory>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

struct IctImportArgs {
  fs::path dir, out;
  IctImportOptions options;
};

void run_import(const IctImportArgs& args) {
  MorphableModel model;
  try {
    model = import_ict_model(args.dir, args.options);
  } catch (const IctImportError& e) {
    throw CommandError(e.what(), kExitDataError);
  }
  save_model_file(args.out, model);
  const double kept = model.stddev.cast<double>().squaredNorm() / model.total_variance;
  fmt::print(
      "{}: {} vertices, {} triangles, {} identity components ({:.1f} % of the identity variance), "
      "{} expressions, {} bytes\n",
      args.out.string(), model.num_vertices(), model.triangles.size(), model.num_components(), 100 * kept,
      model.num_expressions(), fs::file_size(args.out));
}

void add_ict_command(CLI::App& app) {
  auto* ict = app.add_subcommand("ict", "The ICT Face Model Light");
  ict->require_subcommand(1);
  auto args = std::make_shared<IctImportArgs>();
  auto* import = ict->add_subcommand("import", "Convert an ICT FaceXModel directory into a model file (.lpm)");
  import->add_option("--dir", args->dir, "The FaceXModel directory (vertex_indices.json, OBJs)")->required();
  import->add_option("--out", args->out, "Model file to write")->required();
  import->add_option("--vertices", args->options.vertices, "The first vertices to keep (6706: the narrow face area)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  import
      ->add_option("--identity-modes", args->options.identity_modes,
                   "Identity components to keep (0 = the fewest reaching --variance)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  import->add_option("--variance", args->options.variance, "Fraction of the identity variance to keep")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  import->callback([args] { run_import(*args);
});
}  // namespace

const dev::Registration registration(add_ict_command);

}  // namespace lipdrive
}  // namespace lipdrive
