// Who drives the mouth (docs/voice.md, "Hand-over"): the tracked face (video), the
// performer's voice while the face is lost, or the fail-safe when neither is there; and the
// cross-fade between the video's signals and the voice's. Pure computation on fixed-size
// state: step() allocates nothing.
#pragma once

#include "core/drive_signals.hpp"

#include <cstdint>
#include <string_view>

namespace lipdrive {

enum class DriveSource : std::uint8_t { kVideo = 0, kVoice = 1, kFailSafe = 2 };

/// "video", "voice", "fail-safe".
std::string_view drive_source_name(DriveSource source);

/// The tracked face drives; without it the voice while its sound arrives (silent, it holds
/// the rest pose); with neither the fail-safe (hold, then ease to neutral).
DriveSource select_source(bool face_tracked, bool voice_heard);

/// The cross-fade between the two sources of signals. The weight of the voice rises to 1
/// over `crossfade_ns` while the voice drives and falls to 0 while the video does; the
/// signals are (1 - w) · video + w · voice, each side its last value from while it drove, so
/// neither hand-over jumps. Under the fail-safe nothing changes (the channels hold and ease).
class HandOver {
 public:
  explicit HandOver(std::int64_t crossfade_ns) : crossfade_ns_(crossfade_ns) {}

  /// Advances to `now_ns` with `source` driving and returns the signals to drive with;
  /// `video` counts while the video drives, `voice` while the voice does.
  const DriveSignals& step(DriveSource source, const DriveSignals& video, const DriveSignals& voice,
                           std::int64_t now_ns);
  /// 0: the video's signals; 1: the voice's.
  double voice_weight() const { return weight_; }

 private:
  std::int64_t crossfade_ns_;
  DriveSignals video_, voice_, mixed_;
  double weight_ = 0;
  std::int64_t last_ns_ = 0;
  bool stepped_ = false;
};

}  // namespace lipdrive
