#include "firmware_app/config/predictor_file.hpp"

#include "drivers/mapped_file.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fstream>
#include <string>
#include <system_error>

namespace lipdrive {

std::shared_ptr<const ShapePredictorData> load_predictor_file(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec))
    throw CommandError(fmt::format("{}: no such landmark predictor file", path.string()), kExitNoInput);
  std::shared_ptr<const MappedFile> file;
  try {
    file = std::make_shared<const MappedFile>(path);
  } catch (const std::system_error& e) {
    throw CommandError(e.what(), kExitNoInput);
  }
  try {
    if (ShapePredictorData::is_compact(file->bytes())) {
      const auto bytes = file->bytes();
      return std::make_shared<const ShapePredictorData>(ShapePredictorData::read_compact(bytes, std::move(file)));
    }
    file.reset();
    std::ifstream in(path, std::ios::binary);
    if (!in) throw CommandError(fmt::format("{}: cannot open for reading", path.string()), kExitNoInput);
    return std::make_shared<const ShapePredictorData>(ShapePredictorData::read_dlib(in, &FaceDetector::builtin));
  } catch (const ShapePredictorFormatError& e) {
    throw CommandError(fmt::format("{}: {}", path.string(), e.what()), kExitDataError);
  }
}

namespace {

/// The text of a cascade file. Throws CommandError naming it when it cannot be read.
std::shared_ptr<const std::string> read_cascade_file(const std::filesystem::path& path) {
  try {
    const MappedFile file(path);
    const auto bytes = file.bytes();
    return std::make_shared<const std::string>(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  } catch (const std::system_error& e) {
    throw CommandError(e.what(), kExitNoInput);
  }
}

}  // namespace

std::shared_ptr<const CascadeFaceDetector> load_still_cascade(const std::filesystem::path& face,
                                                              const std::filesystem::path& eye) {
  for (const std::filesystem::path& path : {face, eye}) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) {
      spdlog::warn("{}: no such cascade (Debian's opencv-data); stills are searched by dlib's detector alone",
                   path.string());
      return nullptr;
    }
  }
  const std::shared_ptr<const std::string> face_xml = read_cascade_file(face), eye_xml = read_cascade_file(eye);
  try {
    return std::make_shared<const CascadeFaceDetector>(face_xml, eye_xml);
  } catch (const std::runtime_error& e) {
    // The message says which of the two holds no cascade.
    throw CommandError(fmt::format("{} / {}: {}", face.string(), eye.string(), e.what()), kExitDataError);
  }
}

void save_compact_predictor_file(const std::filesystem::path& path, const ShapePredictorData& predictor) {
  replace_file(path, predictor.write_compact());
}

}  // namespace lipdrive
