// Voice activity from the level of feature frames (docs/method.md 11). The level is averaged
// over the last `smoothing_frames` frames; the noise floor is a low quantile (`floor_quantile`)
// of those averages over the last `floor_frames` frames (minimum statistics, after Martin
// 2001: speech pauses often enough that the quiet end of a few seconds is the room); a frame
// is speech when its level stands `margin_db` above the floor, and the voice is active from
// `onset_frames` speech frames in a row until `hangover_frames` frames without speech. Digital
// silence (at or below one step of 16-bit audio, 20 log10(1/32768) = -90.3 dB: a muted input,
// a recording's padding, a decoder's ramp-in) is not the room: it leaves the floor alone and is
// never speech. Pure, fixed-size state, allocation-free.
#pragma once

#include <array>

namespace lipdrive {

/// Frames at or below this level are digital silence, not a quiet room: the level of a
/// signal one 16-bit step (1/32768) in amplitude.
inline constexpr float kDigitalSilenceDb = -90.3f;
inline constexpr int kMaxFloorFrames = 1000;
inline constexpr int kMaxSmoothingFrames = 32;

struct VoiceActivitySettings {
  float margin_db = 15;         // speech stands this far above the floor
  int floor_frames = 200;       // the floor's window (2 s at 100 frames a second), ≤ kMaxFloorFrames
  float floor_quantile = 0.1f;  // the floor: this quantile of the window's levels
  int smoothing_frames = 3;     // the level: the mean over this many frames (dB), ≤ kMaxSmoothingFrames
  int onset_frames = 2;         // speech frames in a row that start the voice
  int hangover_frames = 15;     // frames without speech that end it
  bool operator==(const VoiceActivitySettings&) const = default;
};

/// Why the settings cannot be used, or "".
const char* invalid_voice_activity(const VoiceActivitySettings& settings);

class VoiceActivity {
 public:
  explicit VoiceActivity(const VoiceActivitySettings& settings = {});

  /// One frame's level (dB); true while the voice is active.
  bool step(float level_db);
  bool active() const { return active_; }
  float floor_db() const { return floor_; }
  void reset() { *this = VoiceActivity(settings_); }

 private:
  bool end_run(bool speech);

  VoiceActivitySettings settings_;
  double floor_quantile_;  // settings_.floor_quantile as the decimal it stands for (0.1f is 0.1000000015)
  std::array<float, kMaxSmoothingFrames> recent_{};  // the last levels, for the mean
  std::array<float, kMaxFloorFrames> window_{};      // the last means, for the floor
  std::array<double, kMaxFloorFrames> sorted_{};     // scratch for the quantile
  int recent_count_ = 0, recent_next_ = 0;
  int window_count_ = 0, window_next_ = 0;
  float floor_ = 0;
  bool active_ = false;
  int run_ = 0;  // speech frames in a row, or non-speech frames in a row while active
};

}  // namespace lipdrive
