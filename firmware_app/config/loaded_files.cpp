#include "firmware_app/config/loaded_files.hpp"

#include "core/model_format.hpp"

#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/predictor_file.hpp"

namespace lipdrive {

template <class T, class Load>
std::shared_ptr<const T> LoadedFiles::get(Loaded<T>& slot, const std::filesystem::path& path, Load load) {
  std::error_code size_error, time_error;
  Identity identity{std::filesystem::absolute(path).lexically_normal(), std::filesystem::file_size(path, size_error),
                    std::filesystem::last_write_time(path, time_error)};
  // A file that cannot be looked at is never shared: the loader says what is wrong with it.
  const bool known = !size_error && !time_error;
  if (known && slot.data && slot.identity == identity) return slot.data;
  std::shared_ptr<const T> data = load(path);
  ++reads_;
  if (known) slot = {std::move(identity), data};
  return data;
}

std::shared_ptr<const ShapePredictorData> LoadedFiles::predictor(const std::filesystem::path& path) {
  return get(predictor_, path, [](const std::filesystem::path& p) { return load_predictor_file(p); });
}

std::shared_ptr<const MorphableModel> LoadedFiles::model(const std::filesystem::path& path) {
  return get(model_, path, [this](const std::filesystem::path& p) {
    MorphableModel whole = load_model_file(p);
    model_fingerprint_ = identity_fingerprint(whole);
    return std::make_shared<const MorphableModel>(whole.has_expressions() ? landmark_vertices_only(whole)
                                                                          : std::move(whole));
  });
}

std::uint32_t LoadedFiles::model_fingerprint(const std::filesystem::path& path) {
  model(path);
  return model_fingerprint_;
}

}  // namespace lipdrive
