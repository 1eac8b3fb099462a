// Voice model files (.lpv): deserialize_voice_model, which load_voice_model_file calls on the
// file's bytes. A model that loads is also run as the voice room runs it, on 16,384 samples of
// noise: a file that passes the format checks must not break the features or the predictor.
#include "core/audio_features.hpp"
#include "core/voice_model.hpp"
#include "core/voice_model_format.hpp"

#include <array>
#include <span>
#include <stdexcept>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const lipdrive::VoiceModel model = lipdrive::deserialize_voice_model(std::span(data, size), "fuzz.lpv");
    try {
      lipdrive::AudioFeatures features(model.features);
      lipdrive::VoicePredictor predictor(model);
      std::array<float, 512> block{};
      std::vector<lipdrive::FeatureFrame> frames(block.size() / static_cast<std::size_t>(model.features.hop) + 1);
      std::uint32_t noise = 1;
      lipdrive::VoiceOutput out;
      for (int b = 0; b < 32; ++b) {  // about a second at 16 kHz
        for (float& sample : block) {
          noise = noise * 1664525u + 1013904223u;  // a fixed pseudo-random signal
          sample = static_cast<float>(static_cast<std::int32_t>(noise)) / 2147483648.0f * 0.3f;
        }
        const int count = features.push(block, frames);
        for (int j = 0; j < count; ++j) predictor.push(frames[static_cast<std::size_t>(j)], out);
      }
    } catch (const std::invalid_argument&) {  // documented: the model cannot be run
    } catch (const std::runtime_error&) {     // documented: aubio cannot make its objects
    }
  } catch (const lipdrive::VoiceFormatError&) {
  }
  return 0;
}
