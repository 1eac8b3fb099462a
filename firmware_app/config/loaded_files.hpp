// The large files a process reads to measure frames, the landmark predictor (95 MB for
// Debian's) and the model, loaded once and shared: the daemon's reload builds its new
// processor from the same predictor and model while the old pipeline still runs, instead of
// reading them again and holding two copies.
//
// Thread model: the main thread's; what it hands out is immutable and shared by pointer.
#pragma once

#include "core/morphable_model.hpp"
#include "core/shape_predictor.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>

namespace lipdrive {

class LoadedFiles {
 public:
  /// The predictor in `path`: the one already loaded when the file is the same (path, size and
  /// modification time), else read now (load_predictor_file: throws CommandError naming it).
  std::shared_ptr<const ShapePredictorData> predictor(const std::filesystem::path& path);
  /// The model in `path`, the same way (load_model_file). A model with expression shapes is
  /// kept on its landmark vertices (landmark_vertices_only: all the fit and the measures read;
  /// 6 MB less for the ICT head).
  std::shared_ptr<const MorphableModel> model(const std::filesystem::path& path);
  /// identity_fingerprint() of the whole model in `path`, as read (loads it like model()).
  std::uint32_t model_fingerprint(const std::filesystem::path& path);

  /// How many files were read from disk so far (the rest were shared).
  int reads() const { return reads_; }

 private:
  /// What identifies a file's content cheaply: a replaced or rewritten file is read again.
  struct Identity {
    std::filesystem::path path;
    std::uintmax_t size = 0;
    std::filesystem::file_time_type modified{};
    bool operator==(const Identity&) const = default;
  };
  template <class T>
  struct Loaded {
    Identity identity;
    std::shared_ptr<const T> data;
  };
  template <class T, class Load>
  std::shared_ptr<const T> get(Loaded<T>& slot, const std::filesystem::path& path, Load load);

  // The last one of each: a reload to another file lets the old one go with the old daemon.
  Loaded<ShapePredictorData> predictor_;
  Loaded<MorphableModel> model_;
  std::uint32_t model_fingerprint_ = 0;  // of model_'s file
  int reads_ = 0;
};

}  // namespace lipdrive
