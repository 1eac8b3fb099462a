// A recording named on the command line (a video, an image or a folder of images), opened as
// the offline commands play it: the simulated camera, as fast as possible, once through.
#pragma once

#include "core/image_rotation.hpp"
#include "sim/simulated_camera.hpp"

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

namespace lipdrive {

/// Throws CommandError naming the path: missing or unreadable (exit 66), or not a recording
/// (exit 65).
SimulatedCamera open_recording(const std::filesystem::path& input);

/// The frames of a recording that could not be read, told by its simulated camera's kCorrupt,
/// and what the offline commands make of them: a recording with any is damaged (exit 65), after
/// the frames before and around them were used.
class RecordingDamage {
 public:
  /// One kCorrupt: logs what went wrong (`error`, naming the file) and counts the `lost` frames it
  /// stands for (SimulatedCamera::lost_frames(); none: the file ends early, how much is lost
  /// unknown).
  void add(const std::string& error, std::optional<std::int64_t> lost);
  /// Throws CommandError (exit 65) naming `input` when anything was added, with how many frames
  /// were lost (`pictures`: of a folder's images) and how many `used`.
  void check(const std::filesystem::path& input, std::size_t used, bool pictures) const;

 private:
  std::int64_t lost_ = 0;
  bool ends_early_ = false;
};

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
