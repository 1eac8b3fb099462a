#include "firmware_app/cli/recording.hpp"

#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/daemon/rotated_camera.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <memory>
#include <unistd.h>

namespace lipdrive {

SimulatedCamera open_recording(const std::filesystem::path& input) {
  std::error_code ec;
  if (!std::filesystem::exists(input, ec))
    throw CommandError(fmt::format("{}: no such file or folder", input.string()), kExitNoInput);
  if (::access(input.c_str(), R_OK | (std::filesystem::is_directory(input, ec) ? X_OK : 0)) != 0)
    throw CommandError(fmt::format("{}: permission denied", input.string()), kExitNoInput);
  SimulatedCameraOptions options;  // as fast as possible, no looping
  options.input = input;
  try {
    return SimulatedCamera(options);
  } catch (const SourceError& e) {
    throw CommandError(e.what(), kExitDataError);
  }
}

void RecordingDamage::add(const std::string& error, std::optional<std::int64_t> lost) {
  spdlog::warn("{}", error);
  if (lost)
    lost_ += *lost;
  else
    ends_early_ = true;
}

void RecordingDamage::check(const std::filesystem::path& input, std::size_t used, bool pictures) const {
  if (lost_ == 0 && !ends_early_) return;
  const char* kind = pictures ? "picture" : "frame";
  const std::string lost = fmt::format("{} {}{} could not be decoded", lost_, kind, lost_ == 1 ? "" : "s");
  if (!ends_early_)
    throw CommandError(fmt::format("{}: {} (named above); the other {} were processed", input.string(), lost, used),
                       kExitDataError);
  throw CommandError(fmt::format("{}: the file ends early (named above){}; the {} {}s before its end were processed",
                                 input.string(), lost_ > 0 ? ", and " + lost + " before it" : "", used, kind),
                     kExitDataError);
}

void fit_take_identity(const std::filesystem::path& input, Rotation rotation, FrameProcessor& processor) {
  std::error_code ec;
  // A pipe cannot be read twice: its take is measured as live.
  if (!processor.identity_pending() || !std::filesystem::is_regular_file(input, ec)) return;
  auto recording = std::make_unique<SimulatedCamera>(open_recording(input));
  if (recording->independent_frames()) return;
  const std::unique_ptr<FrameSource> camera = upright(std::move(recording), rotation);
  Frame frame;
  try {
    while (processor.identity_pending()) {
      const GrabStatus status = camera->grab(frame, std::chrono::milliseconds(1000));
      if (status == GrabStatus::kFrame)
        processor.process(frame.gray, frame.cr);
      else if (status != GrabStatus::kCorrupt && status != GrabStatus::kTimeout)
        break;  // the end of the take
    }
  } catch (const std::exception&) {
    // Measured as live: the measuring pass decodes the same frames and says what failed.
  }
  processor.forget(FaceTracker::Next::kVideo);
}

}  // namespace lipdrive
