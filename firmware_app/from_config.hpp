// The parts of the pipeline a configuration describes, for `lipdrive run` and
// `lipdrive calibrate`.
#pragma once

#include "drivers/frame_source.hpp"
#include "firmware_app/config.hpp"
#include "firmware_app/frame_processor.hpp"
#include "firmware_app/side_camera.hpp"

#include <memory>

namespace lipdrive {

/// The configured camera. A recording that cannot be opened throws ConfigError.
std::unique_ptr<FrameSource> make_source(const Config& config);

/// The [side_camera], or nullptr when it is not enabled.
std::unique_ptr<SideCamera> make_side_camera(const Config& config);

/// Model + predictor + fitter. A model that cannot be fitted throws CommandError (exit 65).
std::unique_ptr<FrameProcessor> make_processor(const Config& config);

}  // namespace lipdrive
