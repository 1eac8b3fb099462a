// A recording named on the command line (a video, an image or a folder of images), opened as
// the offline commands play it: the simulated camera, as fast as possible, once through.
#pragma once

#include "core/image_rotation.hpp"
#include "sim/simulated_camera.hpp"

#include <filesystem>

namespace lipdrive {

/// Throws CommandError naming the path: missing or unreadable (exit 66), or not a recording
/// (exit 65).
SimulatedCamera open_recording(const std::filesystem::path& input);

class FrameProcessor;

/// Offline the whole take is there. When `processor` would gather an identity of its own over
/// the take's first tracked frames ([model] auto_identity_frames, no calibrated identity), a
/// pass over those frames of `input` alone (turned by `rotation`) fits it and its rest point
/// first, and the caller then measures the take from its first frame on them, as on a
/// calibrated identity: no frame is fitted on the provisional identity, nor has its ARKit
/// weights held at 0, as live in the daemon, which cannot look ahead (docs/arkit.md). Images
/// gather afresh each (FrameProcessor::forget); a take with fewer tracked frames, or whose
/// frames fail to decode before them, is measured as live (the measuring pass reports the
/// failure, after the rows before it), and so is one that is not a regular file (a pipe cannot
/// be read twice). After a pass, leaves the processor to detect afresh.
void fit_take_identity(const std::filesystem::path& input, Rotation rotation, FrameProcessor& processor);

}  // namespace lipdrive
