// The sample rates sound is taken at anywhere in the product (feature frames, decoded files,
// sound cards, timecode): from the lowest speech is recorded at (telephone sound) to the highest
// a sound card offers. A track at a lower rate is not a recording of a voice.
#pragma once

namespace lipdrive {

inline constexpr int kMinAudioSampleRate = 8000;
inline constexpr int kMaxAudioSampleRate = 192'000;

}  // namespace lipdrive
