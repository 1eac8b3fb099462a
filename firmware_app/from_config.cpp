#include "firmware_app/from_config.hpp"

#include "drivers/v4l2_camera.hpp"
#ifdef LIPDRIVE_HAVE_LIBCAMERA
#include "drivers/libcamera_camera.hpp"
#endif
#include "firmware_app/model_files.hpp"
#include "firmware_app/predictor_file.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>

namespace lipdrive {

std::unique_ptr<FrameSource> make_source(const Config& config) {
  if (config.camera.type == Config::Camera::Type::kV4l2) return std::make_unique<V4l2Camera>(config.camera.v4l2);
#ifdef LIPDRIVE_HAVE_LIBCAMERA
  if (config.camera.type == Config::Camera::Type::kLibcamera) {
    const V4l2Options& format = config.camera.v4l2;
    try {
      return std::make_unique<LibcameraCamera>(
          LibcameraOptions{config.camera.libcamera_id, format.width, format.height, format.frame_rate});
    } catch (const SourceError& e) {
      throw ConfigError(fmt::format("{}: key camera.type: {}", config.file.string(), e.what()));
    }
  }
#endif
  try {
    return std::make_unique<SimulatedCamera>(config.camera.sim);
  } catch (const SourceError& e) {
    throw ConfigError(fmt::format("{}: key camera.input: {}", config.file.string(), e.what()));
  }
}

std::unique_ptr<FrameProcessor> make_processor(const Config& config) {
  const MorphableModel model = load_model_file(config.model.file);
  FitSettings fit;
  fit.iterations = config.model.iterations;
  try {
    return std::make_unique<FrameProcessor>(model, config.model.landmark_set, fit,
                                            load_predictor_file(config.tracker.predictor));
  } catch (const std::invalid_argument& e) {
    throw CommandError(fmt::format("{}: {}", config.model.file.string(), e.what()), kExitDataError);
  }
}

}  // namespace lipdrive
