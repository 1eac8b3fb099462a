#include "core/voice_activity.hpp"

#include "core/statistics.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace lipdrive {

namespace {

/// The double of a float's shortest decimal: the nearest rank of 0.1f of 200 levels must be the
/// 20th, as of 0.1, not the 21st (0.1f · 200 = 20.0000003).
double as_decimal(float value) {
  char text[32];
  const auto written = std::to_chars(text, text + sizeof text, value);
  double decimal = value;
  std::from_chars(text, written.ptr, decimal);
  return decimal;
}

}  // namespace

const char* invalid_voice_activity(const VoiceActivitySettings& s) {
  if (!(s.margin_db > 0 && s.margin_db < 100)) return "margin outside (0, 100) dB";
  if (s.floor_frames < 1 || s.floor_frames > kMaxFloorFrames) return "floor window outside 1..1000 frames";
  if (!(s.floor_quantile >= 0 && s.floor_quantile <= 1)) return "floor quantile outside 0..1";
  if (s.smoothing_frames < 1 || s.smoothing_frames > kMaxSmoothingFrames) return "level smoothing outside 1..32 frames";
  if (s.onset_frames < 1 || s.onset_frames > 1000 || s.hangover_frames < 1 || s.hangover_frames > 10'000)
    return "onset or hangover out of range";
  return "";
}

VoiceActivity::VoiceActivity(const VoiceActivitySettings& settings)
    : settings_(settings), floor_quantile_(as_decimal(settings.floor_quantile)) {}

bool VoiceActivity::end_run(bool speech) {
  if (active_) {
    run_ = speech ? 0 : run_ + 1;
    if (run_ >= settings_.hangover_frames) {
      active_ = false;
      run_ = 0;
    }
  } else {
    run_ = speech ? run_ + 1 : 0;
    if (run_ >= settings_.onset_frames) {
      active_ = true;
      run_ = 0;
    }
  }
  return active_;
}

bool VoiceActivity::step(float level_db) {
  if (level_db <= kDigitalSilenceDb) return end_run(false);
  recent_[static_cast<std::size_t>(recent_next_)] = level_db;
  recent_next_ = (recent_next_ + 1) % settings_.smoothing_frames;
  recent_count_ = std::min(recent_count_ + 1, settings_.smoothing_frames);
  float sum = 0;
  for (int i = 0; i < recent_count_; ++i) sum += recent_[static_cast<std::size_t>(i)];
  const float level = sum / static_cast<float>(recent_count_);

  window_[static_cast<std::size_t>(window_next_)] = level;
  window_next_ = (window_next_ + 1) % settings_.floor_frames;
  window_count_ = std::min(window_count_ + 1, settings_.floor_frames);
  // The quantile by the nearest rank (core/statistics.hpp) over a copy: the window keeps its order.
  std::copy_n(window_.begin(), window_count_, sorted_.begin());
  floor_ =
      static_cast<float>(quantile(std::span(sorted_.data(), static_cast<std::size_t>(window_count_)), floor_quantile_));
  return end_run(level >= floor_ + settings_.margin_db);
}

}  // namespace lipdrive
