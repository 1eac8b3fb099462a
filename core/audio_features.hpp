// Feature frames of speech for the voice model (docs/method.md 11), from aubio: every hop
// (10 ms by default) the newest window of samples (32 ms, Hann) goes through aubio's phase
// vocoder (FFT magnitudes), a mel filter bank (triangular bands evenly spaced on the mel scale,
// Slaney's Auditory Toolbox), the log of the band energies and, for cepstra, the orthonormal
// DCT-II aubio defines (computed here as a small matrix product: aubio's runs on FFTW and
// allocates per call): MFCCs as Davis and Mermelstein (1980) defined them. The frame's level
// (dB of its mean square, over the hop) goes beside them for voice activity detection.
//
// Fixed-size and allocation-free once constructed: push() only fills preallocated buffers.
// Thread model: one owner thread.
#pragma once

#include "core/audio_rates.hpp"

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>


namespace lipdrive {

inline constexpr int kMaxFeatureDims = 64;
inline constexpr int kMaxFeatureHop = 1024;

struct AudioFeatureSettings {
  int sample_rate = 16000;
  int hop = 160;        // samples per feature frame: 10 ms at 16 kHz (100 frames a second)
  int window = 512;     // analysis window in samples, a power of two: 32 ms at 16 kHz
  int mel_bands = 40;   // filter bank bands
  int cepstra = 13;     // MFCCs kept (c0..c12); 0: the log band energies are the features
  float min_hz = 50;    // lowest band edge
  float max_hz = 7600;  // highest band edge, below the Nyquist frequency

  int dims() const { return cepstra > 0 ? cepstra : mel_bands; }
  /// The centre of frame k's window lies this many samples before the end of its hop.
  int centre_lag() const { return window / 2; }
  bool operator==(const AudioFeatureSettings&) const = default;
};

/// Why settings cannot be used, or "" (sizes, rate, band edges).
const char* invalid_feature_settings(const AudioFeatureSettings& settings);

struct FeatureFrame {
  std::array<float, kMaxFeatureDims> values{};  // dims() of them
  float level_db = -120;                        // 10 log10(mean square of the hop's samples), ≥ -120
  std::uint64_t index = 0;                      // frames since the stream began
};

class AudioFeatures {
 public:
  /// Throws std::invalid_argument for unusable settings, std::runtime_error when aubio
  /// cannot make its objects.
  explicit AudioFeatures(const AudioFeatureSettings& settings);
  ~AudioFeatures();
  AudioFeatures(const AudioFeatures&) = delete;
  AudioFeatures& operator=(const AudioFeatures&) = delete;

  /// Feeds samples in [-1, 1]; writes each frame completed on the way into `out` and returns
  /// how many. `out` needs room for samples.size() / hop + 1 frames; frames beyond it are
  /// dropped. A sample that is not a number (a damaged float file) is taken as silence: one
  /// would otherwise make every later frame NaN. Allocates nothing.
  int push(std::span<const float> samples, std::span<FeatureFrame> out);
  /// Starts a new stream: the window empties, frame indices count from 0 (allocates).
  void reset();

  const AudioFeatureSettings& settings() const { return settings_; }
  int dims() const { return settings_.dims(); }
  /// Samples of the hop under way (0..hop-1): the next frame completes after hop - pending() more.
  int pending() const { return filled_; }

  struct Aubio;  // aubio's objects and buffers

 private:
  void analyse(FeatureFrame& frame);

  AudioFeatureSettings settings_;
  // The first settings_.cepstra rows of the orthonormal DCT-II over the mel bands, row after
  // row (audio_features.cpp: why not aubio's).
  std::vector<float> dct_;
  std::unique_ptr<Aubio> aubio_;
  int filled_ = 0;  // samples of the current hop so far
  double hop_energy_ = 0;
  std::uint64_t next_index_ = 0;
};

}  // namespace lipdrive
