#include "firmware_app/config/predictor_file.hpp"

#include "firmware_app/cli/command_error.hpp"

#include <fmt/format.h>

#include <fstream>

namespace lipdrive {

std::shared_ptr<const ShapePredictorData> load_predictor_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw CommandError(fmt::format("{}: no such landmark predictor file", path.string()), kExitNoInput);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw CommandError(fmt::format("{}: cannot open for reading", path.string()), kExitNoInput);
  try {
    return std::make_shared<const ShapePredictorData>(ShapePredictorData::read_dlib(in));
  } catch (const ShapePredictorFormatError& e) {
    throw CommandError(fmt::format("{}: {}", path.string(), e.what()), kExitDataError);
  }
}

}  // namespace lipdrive
