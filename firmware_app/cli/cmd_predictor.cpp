// `lipdrive predictor convert --in FILE.dat --out FILE.lpp`: a dlib 68-point shape predictor
// (Debian's, or one a studio trained with dlib) as lipdrive's compact predictor file, which the
// daemon maps in milliseconds instead of parsing for seconds (core/shape_predictor.hpp).
// `lipdrive predictor info [FILE]`: what a predictor file holds.
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/cli/options.hpp"
#include "firmware_app/config/predictor_file.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <filesystem>
#include <memory>

namespace lipdrive {

void add_predictor_command(CLI::App& app) {
  CLI::App* predictor = app.add_subcommand("predictor", "Landmark predictor files");
  predictor->require_subcommand(1);

  struct Convert {
    std::filesystem::path in, out;
  };
  auto convert = std::make_shared<Convert>();
  CLI::App* convert_cmd =
      predictor->add_subcommand("convert", "Write a dlib 68-point shape predictor (.dat) as a compact .lpp file");
  convert_cmd->add_option("--in", convert->in, "dlib shape predictor (.dat) or .lpp")->required();
  convert_cmd->add_option("--out", convert->out, "compact predictor file to write (.lpp)")->required();
  convert_cmd->callback([convert, convert_cmd] {
    refuse_out_over_input(*convert_cmd);
    const auto data = load_predictor_file(convert->in);
    save_compact_predictor_file(convert->out, *data);
    fmt::print("{}: {} cascades, {} trees of depth {}, {} bytes\n", convert->out.string(), data->num_cascades(),
               data->num_trees(), data->tree_depth(), std::filesystem::file_size(convert->out));
  });

  auto file = std::make_shared<std::filesystem::path>(default_predictor_path());
  CLI::App* info = predictor->add_subcommand("info", "What a predictor file holds");
  info->add_option("FILE", *file, fmt::format("predictor file (default: {})", file->string()));
  info->callback([file] {
    const auto data = load_predictor_file(*file);
    fmt::print("{}: 68 landmarks, {} cascades, {} trees of depth {}, at most {} feature pixels per cascade\n",
               file->string(), data->num_cascades(), data->num_trees(), data->tree_depth(),
               data->max_features_per_cascade());
  });
}

}  // namespace lipdrive
