#include "core/drive_source.hpp"

#include <algorithm>

namespace lipdrive {

std::string_view drive_source_name(DriveSource source) {
  switch (source) {
    case DriveSource::kVideo: return "video";
    case DriveSource::kVoice: return "voice";
    case DriveSource::kFailSafe: return "fail-safe";
  }
  return "fail-safe";
}

DriveSource select_source(bool face_tracked, bool voice_heard) {
  if (face_tracked) return DriveSource::kVideo;
  return voice_heard ? DriveSource::kVoice : DriveSource::kFailSafe;
}

const DriveSignals& HandOver::step(DriveSource source, const DriveSignals& video, const DriveSignals& voice,
                                   std::int64_t now_ns) {
  const double dt_ns = stepped_ ? static_cast<double>(std::max<std::int64_t>(now_ns - last_ns_, 0)) : 0.0;
  last_ns_ = now_ns;
  stepped_ = true;
  const double fade_step = crossfade_ns_ > 0 ? dt_ns / static_cast<double>(crossfade_ns_) : 1.0;
  if (source == DriveSource::kVideo) {
    video_ = video;
    weight_ = std::max(0.0, weight_ - fade_step);
  } else if (source == DriveSource::kVoice) {
    voice_ = voice;
    weight_ = std::min(1.0, weight_ + fade_step);
  }
  // Whole, each source is passed as it is (a NaN of the other source does not leak in as 0 * NaN).
  if (weight_ == 0) return video_;
  if (weight_ == 1) return voice_;
  const auto w = static_cast<float>(weight_);
  for (std::size_t i = 0; i < mixed_.values.size(); ++i)
    mixed_.values[i] = (1 - w) * video_.values[i] + w * voice_.values[i];
  return mixed_;
}

}  // namespace lipdrive
