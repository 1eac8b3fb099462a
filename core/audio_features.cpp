#include "core/audio_features.hpp"

#include <aubio/aubio.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

constexpr float kFloorDb = -120;
// Band energies below this (a silent input) take its log: no -inf reaches the model.
constexpr float kMinBandEnergy = 1e-10f;

}  // namespace

const char* invalid_feature_settings(const AudioFeatureSettings& s) {
  if (s.sample_rate < kMinAudioSampleRate || s.sample_rate > kMaxAudioSampleRate)
    return "sample rate outside 8000..192000 Hz";
  if (s.hop < 16 || s.hop > kMaxFeatureHop) return "hop outside 16..1024 samples";
  if (s.window < s.hop || s.window > 8192 || !std::has_single_bit(static_cast<unsigned>(s.window)))
    return "window must be a power of two, at least the hop, at most 8192";
  if (s.mel_bands < 4 || s.mel_bands > kMaxFeatureDims) return "mel bands outside 4..64";
  if (s.cepstra < 0 || s.cepstra > s.mel_bands) return "cepstra outside 0..mel_bands";
  if (!(s.min_hz >= 0 && s.min_hz < s.max_hz && s.max_hz <= s.sample_rate / 2.0f))
    return "band edges must satisfy 0 <= min_hz < max_hz <= sample rate / 2";
  return "";
}

struct AudioFeatures::Aubio {
  aubio_pvoc_t* pvoc = nullptr;
  aubio_filterbank_t* bank = nullptr;
  fvec_t* hop = nullptr;
  cvec_t* spectrum = nullptr;
  fvec_t* bands = nullptr;

  ~Aubio() {
    if (bands) del_fvec(bands);
    if (spectrum) del_cvec(spectrum);
    if (hop) del_fvec(hop);
    if (bank) del_aubio_filterbank(bank);
    if (pvoc) del_aubio_pvoc(pvoc);
  }
};

namespace {

/// Rows 0..rows-1 of the orthonormal DCT-II of size n (Ahmed, Natarajan and Rao 1974):
/// X_k = s_k sum_i x_i cos(pi k (2i + 1) / 2n), s_0 = sqrt(1/n), s_k = sqrt(2/n). It is the
/// transform aubio_dct_do computes (its header: scipy's dct(x, norm='ortho')), but Debian
/// builds aubio's on FFTW, whose DCT-II allocates a buffer on every call; at most 64 bands
/// need no fast transform, and a matrix product allocates nothing.
std::vector<float> dct_ii_rows(int rows, int n) {
  std::vector<float> m(static_cast<std::size_t>(rows) * static_cast<std::size_t>(n));
  for (int k = 0; k < rows; ++k) {
    const double scale = std::sqrt((k == 0 ? 1.0 : 2.0) / n);
    for (int i = 0; i < n; ++i)
      m[static_cast<std::size_t>(k * n + i)] =
          static_cast<float>(scale * std::cos(std::numbers::pi * k * (2 * i + 1) / (2.0 * n)));
  }
  return m;
}

std::unique_ptr<AudioFeatures::Aubio> make_aubio(const AudioFeatureSettings& settings) {
  auto made = std::make_unique<AudioFeatures::Aubio>();
  const auto window = static_cast<uint_t>(settings.window), hop = static_cast<uint_t>(settings.hop);
  const auto bands = static_cast<uint_t>(settings.mel_bands);
  AudioFeatures::Aubio& a = *made;
  a.pvoc = new_aubio_pvoc(window, hop);
  a.bank = new_aubio_filterbank(bands, window);
  a.hop = new_fvec(hop);
  a.spectrum = new_cvec(window);
  a.bands = new_fvec(bands);
  if (!a.pvoc || !a.bank || !a.hop || !a.spectrum || !a.bands)
    throw std::runtime_error("audio features: aubio cannot make its phase vocoder or filter bank");
  if (aubio_filterbank_set_mel_coeffs(a.bank, static_cast<smpl_t>(settings.sample_rate), settings.min_hz,
                                      settings.max_hz) != 0)
    throw std::runtime_error("audio features: aubio cannot make the mel filter bank");
  return made;
}

}  // namespace

AudioFeatures::AudioFeatures(const AudioFeatureSettings& settings) : settings_(settings) {
  if (const std::string problem = invalid_feature_settings(settings); !problem.empty())
    throw std::invalid_argument("audio features: " + problem);
  dct_ = dct_ii_rows(settings_.cepstra, settings_.mel_bands);
  aubio_ = make_aubio(settings_);
}

AudioFeatures::~AudioFeatures() = default;

void AudioFeatures::reset() {
  // aubio's phase vocoder keeps its window inside: new objects start empty.
  aubio_ = make_aubio(settings_);
  filled_ = 0;
  hop_energy_ = 0;
  next_index_ = 0;
}

int AudioFeatures::push(std::span<const float> samples, std::span<FeatureFrame> out) {
  int written = 0;
  fvec_t& hop = *aubio_->hop;
  for (const float heard : samples) {
    const float sample = std::isfinite(heard) ? heard : 0.0f;
    hop.data[filled_++] = sample;
    hop_energy_ += static_cast<double>(sample) * sample;
    if (filled_ < settings_.hop) continue;
    FeatureFrame scratch;
    FeatureFrame& frame = written < static_cast<int>(out.size()) ? out[static_cast<std::size_t>(written++)] : scratch;
    analyse(frame);
    filled_ = 0;
    hop_energy_ = 0;
  }
  return written;
}

void AudioFeatures::analyse(FeatureFrame& frame) {
  Aubio& a = *aubio_;
  aubio_pvoc_do(a.pvoc, a.hop, a.spectrum);
  aubio_filterbank_do(a.bank, a.spectrum, a.bands);
  const int bands = settings_.mel_bands;
  for (int b = 0; b < bands; ++b) a.bands->data[b] = std::log(std::max(a.bands->data[b], kMinBandEnergy));
  if (settings_.cepstra > 0) {
    for (int c = 0; c < settings_.cepstra; ++c) {
      const float* row = &dct_[static_cast<std::size_t>(c * bands)];
      double sum = 0;
      for (int b = 0; b < bands; ++b) sum += static_cast<double>(row[b]) * a.bands->data[b];
      frame.values[static_cast<std::size_t>(c)] = static_cast<float>(sum);
    }
  } else {
    std::copy_n(a.bands->data, bands, frame.values.begin());
  }
  const double mean_square = hop_energy_ / settings_.hop;
  frame.level_db = mean_square > 0 ? std::max(kFloorDb, static_cast<float>(10 * std::log10(mean_square))) : kFloorDb;
  frame.index = next_index_++;
}

}  // namespace lipdrive
