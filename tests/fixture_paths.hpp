// The built files the tests run on: the default model and the generated talking-face clip,
// and the configuration lines that replay that clip to the daemon like a 60 fps camera.
#pragma once

#include <fmt/format.h>

#include <filesystem>
#include <string>

namespace lipdrive::test {

inline const std::filesystem::path kModel = std::filesystem::path(LIPDRIVE_MODEL_DIR) / "default.lpm";
inline const std::filesystem::path kClip = std::filesystem::path(LIPDRIVE_FIXTURE_DIR) / "talking_face.avi";

/// [model] and [camera] of a daemon configuration replaying kClip in real time at 60 fps,
/// looped; more [camera] keys may follow.
inline std::string sim_camera_at_60_fps() {
  return fmt::format(
      "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\nreal_time = true\nloop = true\nreplay_fps = 60\n",
      kModel.string(), kClip.string());
}

}  // namespace lipdrive::test
