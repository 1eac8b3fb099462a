#include "firmware_app/config/paths.hpp"

namespace lipdrive {
namespace {

std::filesystem::path exe_directory() { return std::filesystem::read_symlink("/proc/self/exe").parent_path(); }

}  // namespace

std::filesystem::path model_directory() {
  const auto exe_dir = exe_directory();
  const auto build_tree = exe_dir / "models";
  if (std::filesystem::is_directory(build_tree)) return build_tree;
  return exe_dir.parent_path() / "share" / "lipdrive" / "models";
}

std::filesystem::path default_model_path() { return model_directory() / "ict_face_light.lpm"; }

std::filesystem::path default_predictor_path() {
  const auto compact = model_directory() / "face_landmarks.lpp";
  std::error_code ec;
  return std::filesystem::exists(compact, ec) ? compact : std::filesystem::path(kDebianPredictorPath);
}

std::filesystem::path default_fixture_path() {
  const auto exe_dir = exe_directory();
  const auto build_tree = exe_dir / "fixtures" / "talking_face.avi";
  if (std::filesystem::exists(build_tree)) return build_tree;
  return exe_dir.parent_path() / "share" / "lipdrive" / "talking_face.avi";
}

}  // namespace lipdrive
