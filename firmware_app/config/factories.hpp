// The parts of the pipeline a configuration describes: the one place that builds cameras and
// the per-frame processor, for `lipdrive run`, `lipdrive calibrate` and `lipdrive process`
// alike, so that offline results and the rig's come from the same settings.
#pragma once

#include "core/calibration.hpp"
#include "drivers/frame_source.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/loaded_files.hpp"
#include "firmware_app/daemon/frame_processor.hpp"
#include "firmware_app/daemon/side_camera.hpp"
#include "firmware_app/daemon/timecode_source.hpp"
#include "firmware_app/daemon/voice_room.hpp"
#include "sim/replay_clock.hpp"

#include <memory>

namespace lipdrive {

/// The configured camera. A recording or a libcamera camera that cannot be opened throws
/// ConfigError (a libcamera camera not there yet only where it is not waited for,
/// Config::Camera::wait_when_absent). `clock` (not owned, outlives the camera): the simulated
/// camera's replay timeline, shared with the simulated microphone of [voice] input = "sim".
std::unique_ptr<FrameSource> make_source(const Config& config, ReplayClock* clock = nullptr);

/// The [voice] room, or nullptr when it is not enabled or cannot run: a voice model that
/// cannot be loaded or was trained for another sample rate, or a clip without sound, is logged
/// naming the file and the daemon drives from the video alone. A sound card that cannot be
/// opened yet is logged and retried (video only meanwhile). `clock`: the simulated camera's
/// timeline, with its loop's length, for input "sim".
std::unique_ptr<VoiceRoom> make_voice_room(const Config& config, ReplayClock* clock, TakeSound* sound);

/// The voice model [voice] model names, for the rate the input delivers. Throws CommandError
/// naming the file (missing: exit 66, invalid: 65) or ConfigError naming voice.sample_rate
/// when the model was trained on sound at another rate.
VoiceModel load_voice(const Config& config);

/// The [side_camera], or nullptr when it is not enabled.
std::unique_ptr<SideCamera> make_side_camera(const Config& config);

/// The [timecode] source, or nullptr when frames are not stamped.
std::unique_ptr<TimecodeSource> make_timecode(const Config& config);

/// Opens, once, the audio inputs the configuration names (ALSA devices for LTC and the voice), which the
/// daemon itself does not insist on at start (a device may appear later): for
/// `lipdrive check-config`. Throws ConfigError naming the file, the key and the device.
void check_audio_inputs(const Config& config);

/// The profile of [performer] name (the uncalibrated defaults when no performer is named).
/// Throws CommandError naming the file when it is missing or malformed.
PerformerProfile load_performer(const Config& config);

/// Model + predictor + tracker + fitter from [model] and [tracker], the files from `files`
/// (shared with earlier processors when unchanged), the fit on the performer's identity when
/// `profile` holds one of this model (else the mean face; one of another model is ignored
/// with a warning). Throws CommandError: a missing model or predictor (exit 66), one that is
/// invalid or cannot be fitted (exit 65).
std::unique_ptr<FrameProcessor> make_processor(const Config& config, LoadedFiles& files,
                                               const PerformerProfile& profile);
/// The same for a command that builds one processor.
inline std::unique_ptr<FrameProcessor> make_processor(const Config& config, const PerformerProfile& profile) {
  LoadedFiles files;
  return make_processor(config, files, profile);
}

}  // namespace lipdrive
