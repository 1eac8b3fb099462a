// The sample rates sound is taken at anywhere in the product (feature frames, decoded files,
// sound cards, timecode): from the lowest speech is recorded at (telephone sound) to the highest
// a sound card offers. A track at a lower rate is not a recording of a voice.
#pragma once

namespace lipdrive {

inline constexpr int kMinAudioSampleRate = 8000;
inline constexpr int kMaxAudioSampleRate = 192'000;
/// The highest rate a voice model is trained and run at (`[voice] sample_rate`, `voice train
/// --sample-rate`): speech holds nothing above 8 kHz the model uses, and a higher rate only
/// costs the voice thread time.
inline constexpr int kMaxVoiceSampleRate = 48'000;

}  // namespace lipdrive
