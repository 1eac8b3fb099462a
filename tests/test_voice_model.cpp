// The voice model's parts: aubio features, voice activity, the streaming predictor (its
// context, gating and allocation-free step), training on synthetic speech-like sound whose
// "mouth" is known, the .lpv format, and the speech-frame agreement metric.
#include "allocation_counter.hpp"
#include "core/audio_features.hpp"
#include "core/byte_io.hpp"
#include "core/metrics.hpp"
#include "core/voice_activity.hpp"
#include "core/voice_model.hpp"
#include "core/voice_model_format.hpp"
#include "core/voice_training.hpp"

#include <aubio/aubio.h>
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <functional>
#include <numbers>
#include <random>

namespace lipdrive {
namespace {

std::vector<float> tone(double hz, double seconds, double amplitude, int rate = 16000) {
  std::vector<float> s(static_cast<std::size_t>(seconds * rate));
  for (std::size_t i = 0; i < s.size(); ++i)
    s[i] = static_cast<float>(amplitude * std::sin(2 * std::numbers::pi * hz * static_cast<double>(i) / rate));
  return s;
}

// ---- features -----------------------------------------------------------------------------

TEST(AudioFeatures, ALoudToneLightsItsOwnMelBandAndReadsItsLevel) {
  AudioFeatureSettings settings;
  settings.cepstra = 0;  // the log band energies themselves
  const std::vector<float> sound = tone(1000, 0.5, 0.5);
  const std::vector<FeatureFrame> frames = extract_features(settings, sound);
  ASSERT_EQ(frames.size(), sound.size() / 160);
  const FeatureFrame& f = frames.back();
  const int loudest = static_cast<int>(std::max_element(f.values.begin(), f.values.begin() + 40) - f.values.begin());
  // 1 kHz on a mel scale from 50 to 7600 Hz over 40 bands: band 13 or so (about 1000 mel).
  EXPECT_GE(loudest, 11);
  EXPECT_LE(loudest, 15);
  EXPECT_NEAR(f.level_db, 10 * std::log10(0.125), 0.1);  // mean square of a 0.5 sine
  EXPECT_EQ(f.index, frames.size() - 1);
  const std::vector<FeatureFrame> quiet = extract_features(settings, std::vector<float>(1600, 0.0f));
  EXPECT_EQ(quiet.back().level_db, -120.0f);
  for (int b = 0; b < 40; ++b) EXPECT_TRUE(std::isfinite(quiet.back().values[static_cast<std::size_t>(b)]));
}

// The cepstra are aubio's DCT-II of the log band energies: the allocation-free product in
// core/audio_features.cpp gives what aubio_dct_do gives, every coefficient of every frame.
TEST(AudioFeatures, CepstraAreAubiosDctOfTheLogBands) {
  AudioFeatureSettings bands_only, cepstra;
  bands_only.cepstra = 0;
  cepstra.cepstra = cepstra.mel_bands;
  std::mt19937 random(5);
  std::normal_distribution<float> noise(0, 0.1f);
  std::vector<float> sound = tone(440, 0.4, 0.3);
  for (float& s : sound) s += noise(random);
  const std::vector<FeatureFrame> logs = extract_features(bands_only, sound);
  const std::vector<FeatureFrame> ours = extract_features(cepstra, sound);
  ASSERT_EQ(logs.size(), ours.size());
  ASSERT_GT(ours.size(), 30u);
  const auto n = static_cast<uint_t>(cepstra.mel_bands);
  aubio_dct_t* dct = new_aubio_dct(n);
  fvec_t* in = new_fvec(n);
  fvec_t* out = new_fvec(n);
  double worst = 0;
  for (std::size_t f = 0; f < ours.size(); ++f) {
    std::copy_n(logs[f].values.begin(), n, in->data);
    aubio_dct_do(dct, in, out);
    for (uint_t k = 0; k < n; ++k)
      worst = std::max(worst, std::abs(static_cast<double>(ours[f].values[k]) - out->data[k]) /
                                  std::max(1.0, std::abs(static_cast<double>(out->data[k]))));
  }
  del_fvec(out);
  del_fvec(in);
  del_aubio_dct(dct);
  EXPECT_LT(worst, 1e-5) << "largest difference from aubio_dct_do, relative to the coefficient (at least 1)";
}

TEST(AudioFeatures, BlocksOfAnySizeGiveTheSameFramesWithoutAllocating) {
  const AudioFeatureSettings settings;  // 13 MFCCs
  std::mt19937 random(3);
  std::normal_distribution<float> noise(0, 0.1f);
  std::vector<float> sound(16000);
  for (float& s : sound) s = noise(random);
  const std::vector<FeatureFrame> whole = extract_features(settings, sound);

  AudioFeatures features(settings);
  std::array<FeatureFrame, 8> out;
  std::vector<FeatureFrame> pieces;
  std::size_t at = 0;
  long allocations = 0;
  // Each block size in turn, up to its share of the sound.
  for (const auto& [block, until] : {std::pair<std::size_t, std::size_t>{100, 3000}, {333, 6000}, {160, 8000},
                                    {7, 9000}, {1024, 16000}}) {
    for (; at + block <= until; at += block) {
      test::count_allocations_on_this_thread(true);
      const long before = test::allocation_count();
      const int made = features.push({sound.data() + at, block}, out);
      allocations += test::allocation_count() - before;
      test::count_allocations_on_this_thread(false);
      pieces.insert(pieces.end(), out.begin(), out.begin() + made);
    }
  }
  EXPECT_EQ(allocations, 0) << "push() allocates nothing";
  ASSERT_GT(pieces.size(), 40u);
  for (std::size_t i = 0; i < pieces.size(); ++i)
    for (int d = 0; d < settings.dims(); ++d)
      ASSERT_FLOAT_EQ(pieces[i].values[static_cast<std::size_t>(d)], whole[i].values[static_cast<std::size_t>(d)])
          << "frame " << i;
}

TEST(AudioFeatures, ASampleThatIsNotANumberIsSilenceNotTheEndOfTheFeatures) {
  const AudioFeatureSettings settings;
  std::mt19937 random(5);
  std::normal_distribution<float> noise(0, 0.1f);
  std::vector<float> sound(8000);
  for (float& s : sound) s = noise(random);
  std::vector<float> damaged = sound, silenced = sound;
  damaged[1600] = std::nanf("");
  damaged[1601] = INFINITY;
  silenced[1600] = silenced[1601] = 0;
  const std::vector<FeatureFrame> read = extract_features(settings, damaged);
  const std::vector<FeatureFrame> expected = extract_features(settings, silenced);
  ASSERT_EQ(read.size(), expected.size());
  for (std::size_t i = 0; i < read.size(); ++i) {
    ASSERT_TRUE(std::isfinite(read[i].level_db)) << "frame " << i;
    for (int d = 0; d < settings.dims(); ++d)
      ASSERT_EQ(read[i].values[static_cast<std::size_t>(d)], expected[i].values[static_cast<std::size_t>(d)])
          << "frame " << i;
  }
}

TEST(AudioFeatures, FrameAtPlacesTimesOnWindowCentres) {
  const AudioFeatureSettings s;  // hop 160, window 512: frame k centred at (k+1)·160 - 256 samples
  EXPECT_EQ(frame_at(s, (5 * 160 + 160 - 256) / 16000.0), 5);
  EXPECT_EQ(frame_at(s, 1.0), 101);  // 16000 + 256 = 101.6 hops
  EXPECT_EQ(frame_at(s, 0.0), 1);  // centred at +4 ms; frame 0 at -6 ms
}

// ---- voice activity -----------------------------------------------------------------------

TEST(VoiceActivity, SpeechAboveTheFloorStartsAfterTheOnsetAndEndsAfterTheHangover) {
  VoiceActivitySettings settings;
  settings.onset_frames = 2;
  settings.hangover_frames = 5;
  settings.smoothing_frames = 1;
  VoiceActivity vad(settings);
  EXPECT_FALSE(vad.step(-120)) << "digital silence";
  EXPECT_FALSE(vad.step(-96)) << "a decoder's ramp-in, under one 16-bit step: digital silence too";
  for (int i = 0; i < 50; ++i) EXPECT_FALSE(vad.step(i % 2 ? -60 : -50)) << "a fluctuating room";
  EXPECT_NEAR(vad.floor_db(), -60, 1e-6) << "the floor is the quiet end of the room, not the digital silence";
  EXPECT_FALSE(vad.step(-20));  // one loud frame is not speech yet
  EXPECT_TRUE(vad.step(-20));
  for (int i = 0; i < 30; ++i) EXPECT_TRUE(vad.step(-25));
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(vad.step(-60)) << "hangover " << i;
  EXPECT_FALSE(vad.step(-60));
  // A noise floor that grows is followed within the floor's window (2 s).
  for (int i = 0; i < 250; ++i) vad.step(-40);
  EXPECT_FALSE(vad.active());
  EXPECT_NEAR(vad.floor_db(), -40, 0.1);
}

TEST(VoiceActivity, TheFloorIsTheNearestRankOfTheQuantileAsWritten) {
  VoiceActivitySettings settings;  // floor_quantile 0.1f of 200 frames: the 20th lowest
  settings.smoothing_frames = 1;
  VoiceActivity vad(settings);
  for (int i = 0; i < 200; ++i) vad.step(-80.0f + static_cast<float>(i) * 0.1f);  // -80.0, -79.9, ...
  EXPECT_NEAR(vad.floor_db(), -78.1f, 1e-4) << "the 20th of 200 levels (0.1 of 200), not the 21st";
}

// ---- the predictor ------------------------------------------------------------------------

/// A linear model on 2-dimensional features that outputs, for `open`, feature 0 of the frame
/// `offset` frames from the prediction's own.
VoiceModel picking_model(int offset) {
  VoiceModel m;
  m.features.cepstra = 2;
  m.features.mel_bands = 4;
  m.context = {.past = 4, .lookahead = 2, .stride = 2};  // taps at -4, -2, 0, 2
  m.feature_mean = Eigen::VectorXf::Zero(2);
  m.feature_scale = Eigen::VectorXf::Ones(2);
  m.weights = Eigen::MatrixXf::Zero(kNumVoiceTargets, m.inputs());
  m.weights(0, ((offset + 4) / 2) * 2) = 1;
  m.bias = Eigen::VectorXf::Zero(kNumVoiceTargets);
  m.gain.fill(1);
  m.smoothing_s = 0;
  m.gate_s = 0;
  m.activity.margin_db = 10;
  m.activity.onset_frames = 1;
  m.activity.smoothing_frames = 1;
  return m;
}

TEST(VoicePredictor, StacksItsContextAroundTheFrameALookAheadBack) {
  for (int offset : {-4, -2, 0, 2}) {
    VoicePredictor predictor(picking_model(offset));
    VoiceOutput out;
    int made = 0;
    for (int k = 0; k < 20; ++k) {
      FeatureFrame f;
      f.values[0] = static_cast<float>(k);
      f.level_db = k == 0 ? -80 : -20;  // loud from frame 1 on: the voice is active
      f.index = static_cast<std::uint64_t>(k);
      if (!predictor.push(f, out)) continue;
      ++made;
      EXPECT_EQ(out.frame, static_cast<std::uint64_t>(k - 2)) << "the prediction is for the frame 2 back";
      EXPECT_FLOAT_EQ(out.values[0], static_cast<float>(k - 2 + offset)) << "offset " << offset << " at " << k;
    }
    EXPECT_EQ(made, 20 - 6) << "the first 4 + 2 frames fill the context";
  }
  const VoiceModel m = picking_model(0);
  EXPECT_NEAR(m.delay_s(), (2 * 160 + 256) / 16000.0, 1e-9);
}

TEST(VoicePredictor, SilenceHoldsTheRestPoseAndStepsWithoutAllocating) {
  VoiceModel m = picking_model(0);
  m.rest = {0.01f, 1.3f, 0.0f, 0.9f};
  m.gate_s = 0.03f;  // three frames to fade
  m.activity.hangover_frames = 2;
  VoicePredictor predictor(m);
  VoiceOutput out;
  FeatureFrame f;
  f.values[0] = 5;
  f.level_db = -80;
  std::vector<float> open;
  long allocations = 0;
  for (int k = 0; k < 40; ++k) {
    f.index = static_cast<std::uint64_t>(k);
    f.level_db = k >= 20 && k < 30 ? -20 : -80;
    test::count_allocations_on_this_thread(true);
    const long before = test::allocation_count();
    const bool made = predictor.push(f, out);
    allocations += test::allocation_count() - before;
    test::count_allocations_on_this_thread(false);
    if (made) open.push_back(out.values[0]);
  }
  EXPECT_EQ(allocations, 0);
  ASSERT_EQ(open.size(), 34u);
  EXPECT_FLOAT_EQ(open[5], 0.01f) << "silent: the rest pose";
  EXPECT_FLOAT_EQ(out.values[1], 1.3f);
  // Frames 20.. are loud: the gate opens over 3 frames to the prediction (5).
  EXPECT_NEAR(open[20 - 6 + 3], 5.0f, 1e-5);
  EXPECT_GT(open[20 - 6], 0.01f);
  EXPECT_LT(open[20 - 6], 5.0f);
}

TEST(VoicePredictor, AModelThatDoesNotFitTogetherIsRejected) {
  VoiceModel m = picking_model(0);
  m.weights = Eigen::MatrixXf::Zero(kNumVoiceTargets, 3);
  EXPECT_THROW(VoicePredictor{m}, std::invalid_argument);
  m = picking_model(0);
  m.feature_scale[1] = 0;
  EXPECT_NE(invalid_voice_model(m), "");
  m = picking_model(0);
  m.bias[2] = std::nanf("");
  EXPECT_NE(invalid_voice_model(m), "");
}

// ---- training -----------------------------------------------------------------------------

/// Speech-like sound with a known mouth: syllables of a buzz whose loudness and brightness
/// follow the "opening", silent between sentences; the targets are the opening at 25 fps.
VoiceRecording synthetic_recording(unsigned seed, double seconds = 6) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  const int rate = 16000;
  VoiceRecording r;
  r.name = "synthetic" + std::to_string(seed);
  r.sample_rate = rate;
  r.has_transcript = true;
  const auto n = static_cast<std::size_t>(seconds * rate);
  std::vector<double> opening(n, 0.0);
  // Syllables 150-300 ms long, of random depth, from 0.5 s to 1 s before the end.
  for (double t = 0.5; t < seconds - 1.0;) {
    const double length = 0.15 + 0.15 * uniform(random), depth = 0.3 + 0.7 * uniform(random);
    for (std::size_t i = static_cast<std::size_t>(t * rate); i < static_cast<std::size_t>((t + length) * rate); ++i)
      opening[i] = depth * std::sin(std::numbers::pi * (static_cast<double>(i) / rate - t) / length);
    t += length + 0.02;
  }
  r.samples.resize(n);
  double phase = 0;
  std::normal_distribution<double> noise(0, 1);
  for (std::size_t i = 0; i < n; ++i) {
    const double o = opening[i];
    phase += 2 * std::numbers::pi * (120 + 60 * o) / rate;
    // Brighter (more harmonics) and louder when open, plus a faint room noise.
    const double voice = o * (std::sin(phase) + o * 0.6 * std::sin(3 * phase) + o * 0.4 * std::sin(7 * phase));
    r.samples[i] = static_cast<float>(0.2 * voice + 0.001 * noise(random));
  }
  for (int frame = 0; frame < static_cast<int>(seconds * 25); ++frame) {
    VoiceTargetFrame target;
    target.time_s = frame / 25.0;
    const double o = opening[std::min(n - 1, static_cast<std::size_t>(target.time_s * rate))];
    target.values = {static_cast<float>(0.05 + 0.3 * o), static_cast<float>(1.3 - 0.1 * o), 0.0f,
                     static_cast<float>(o < 0.05 ? 0.9 : 0.1)};
    target.tracked = frame % 17 != 5;  // a few frames were not tracked
    target.speech = o > 0.02;
    r.targets.push_back(target);
  }
  return r;
}

TEST(VoiceTraining, LearnsAKnownMouthFromSoundAndGeneralisesToAnotherRecording) {
  std::vector<VoiceRecording> train;
  for (unsigned seed = 1; seed <= 6; ++seed) train.push_back(synthetic_recording(seed));
  VoiceTrainingSettings settings;
  settings.context = {.past = 10, .lookahead = 2, .stride = 2};
  settings.hidden = 0;  // ridge regression: the hidden layer has a test of its own
  const VoiceModel model = train_voice_model(train, settings);
  EXPECT_EQ(invalid_voice_model(model), "");
  EXPECT_NEAR(model.rest[0], 0.05f, 0.01f) << "the rest pose: the silent frames' opening";
  const VoiceRecording test = synthetic_recording(99);
  const std::vector<VoiceOutput> out = predict_recording(model, test);
  std::vector<double> truth, voice;
  std::vector<bool> speech;
  for (std::size_t i = 0; i < out.size(); ++i) {
    truth.push_back(test.targets[i].tracked ? test.targets[i].values[0] : std::nan(""));
    voice.push_back(out[i].values[0]);
    speech.push_back(test.targets[i].speech);
  }
  const int last = static_cast<int>(out.size()) - 1;
  const SpeechAgreement a = speech_agreement(truth, voice, speech, last - 15, last);
  EXPECT_GT(a.pearson_r, 0.8);
  EXPECT_GT(a.std_ratio, 0.8) << "the gain keeps the spread";
  EXPECT_LT(a.std_ratio, 1.25);
  EXPECT_LT(a.silence_distance, 0.05);
}

TEST(VoiceTraining, AHiddenLayerTrainsToAValidModel) {
  std::vector<VoiceRecording> train;
  for (unsigned seed = 1; seed <= 4; ++seed) train.push_back(synthetic_recording(seed, 4));
  VoiceTrainingSettings settings;
  settings.context = {.past = 6, .lookahead = 2, .stride = 2};
  settings.hidden = 8;
  settings.epochs = 50;
  const VoiceModel model = train_voice_model(train, settings);
  EXPECT_EQ(model.hidden(), 8);
  EXPECT_EQ(invalid_voice_model(model), "");
}

TEST(VoiceTraining, TooLittleMaterialOrAnotherSampleRateIsAnError) {
  std::vector<VoiceRecording> train{synthetic_recording(1, 2)};
  VoiceTrainingSettings settings;
  settings.context = {.past = 100, .lookahead = 8, .stride = 1};  // 109 taps · 13: far more inputs than frames
  EXPECT_THROW(train_voice_model(train, settings), std::invalid_argument);
  train[0].sample_rate = 22050;
  EXPECT_THROW(train_voice_model(train, VoiceTrainingSettings{}), std::invalid_argument);
}

TEST(VoiceTraining, TheSoundOfAGapInTheVideoIsNoSample) {
  // 6 s of sound, the video's rows for the first and the last second only: some 100 samples
  // each (one per 10 ms feature frame), none in the 4 s between (400 more if they were filled).
  VoiceRecording gap = synthetic_recording(1, 6);
  std::erase_if(gap.targets, [](const VoiceTargetFrame& t) { return t.time_s >= 1 && t.time_s < 5; });
  for (VoiceTargetFrame& t : gap.targets) t.tracked = true;
  const std::vector<VoiceRecording> train{gap};
  VoiceTrainingSettings settings;
  settings.context = {.past = 100, .lookahead = 8, .stride = 1};  // more inputs than samples: the error counts them
  try {
    train_voice_model(train, settings);
    FAIL() << "trained on too little material";
  } catch (const std::invalid_argument& e) {
    const std::string message = e.what(), prefix = "voice training: ";
    ASSERT_EQ(message.rfind(prefix, 0), 0u) << message;
    const int samples = std::stoi(message.substr(prefix.size()));
    EXPECT_GE(samples, 190) << message;
    EXPECT_LE(samples, 210) << message;
  }
}

// ---- the file format ----------------------------------------------------------------------

VoiceModel small_trained_model() {
  std::vector<VoiceRecording> train{synthetic_recording(1, 3), synthetic_recording(2, 3)};
  VoiceTrainingSettings settings;
  settings.context = {.past = 4, .lookahead = 2, .stride = 2};
  settings.hidden = 3;
  settings.epochs = 5;
  return train_voice_model(train, settings);
}

std::string format_error(std::span<const std::uint8_t> bytes) {
  try {
    deserialize_voice_model(bytes, "voice.lpv");
  } catch (const VoiceFormatError& e) {
    return e.what();
  }
  return "";
}

TEST(VoiceModelFormat, RoundTripsExactly) {
  const VoiceModel model = small_trained_model();
  const std::vector<std::uint8_t> bytes = serialize_voice_model(model);
  const VoiceModel back = deserialize_voice_model(bytes, "voice.lpv");
  EXPECT_EQ(back.features, model.features);
  EXPECT_EQ(back.context, model.context);
  EXPECT_EQ(back.activity, model.activity);
  EXPECT_EQ(back.hidden_weights, model.hidden_weights);
  EXPECT_EQ(back.weights, model.weights);
  EXPECT_EQ(back.feature_scale, model.feature_scale);
  EXPECT_EQ(back.gain, model.gain);
  EXPECT_EQ(back.rest, model.rest);
  EXPECT_EQ(serialize_voice_model(back), bytes);
}

TEST(VoiceModelFormat, DamageIsAnErrorNamingTheFile) {
  const std::vector<std::uint8_t> good = serialize_voice_model(small_trained_model());
  std::vector<std::uint8_t> bytes = good;
  bytes[100] ^= 0x40;
  EXPECT_NE(format_error(bytes).find("voice.lpv: checksum mismatch"), std::string::npos);
  EXPECT_NE(format_error(std::span(good).first(good.size() - 4)).find("voice.lpv: truncated"), std::string::npos);
  EXPECT_NE(format_error(std::span(good).first(10)).find("truncated"), std::string::npos);
  bytes = good;
  bytes[0] = 'X';
  EXPECT_NE(format_error(bytes).find("not a lipdrive voice model"), std::string::npos);
  bytes = good;
  bytes[8] = 2;
  EXPECT_NE(format_error(bytes).find("unsupported format version 2"), std::string::npos);
}

/// `good` with the payload changed by `edit` and the checksum made right again: what a
/// careless writer, not a damaged disk, would produce.
std::vector<std::uint8_t> rewritten(std::vector<std::uint8_t> bytes,
                                    const std::function<void(std::vector<std::uint8_t>&)>& edit) {
  edit(bytes);
  const std::uint32_t crc = crc32(std::span(bytes).subspan(kVoiceHeaderSize));
  for (int i = 0; i < 4; ++i) bytes[20 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(crc >> (8 * i));
  return bytes;
}

TEST(VoiceModelFormat, ImpossibleSizesAndValuesAreRejectedBeforeAllocating) {
  const std::vector<std::uint8_t> good = serialize_voice_model(small_trained_model());
  // Payload field 17 is the hidden unit count (after 5 + 2 + 2 + 4 + 3 fields).
  const std::size_t hidden_at = kVoiceHeaderSize + 16 * 4;
  EXPECT_NE(format_error(rewritten(good, [&](auto& b) { b[hidden_at + 3] = 0x7f; })).find("hidden units"),
            std::string::npos);
  EXPECT_NE(format_error(rewritten(good, [&](auto& b) { b[hidden_at] = 4; })).find("sizes inconsistent"),
            std::string::npos);
  // The sample rate (the first field) at 7 Hz.
  EXPECT_NE(format_error(rewritten(good, [&](auto& b) {
              b[kVoiceHeaderSize] = 7;
              b[kVoiceHeaderSize + 1] = 0;
            })).find("sample rate"),
            std::string::npos);
  // A NaN in the last float (the gate time).
  EXPECT_NE(format_error(rewritten(good, [&](auto& b) {
              const std::uint32_t nan = 0x7fc00000;
              for (int i = 0; i < 4; ++i) b[b.size() - 4 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(nan >> (8 * i));
            })).find("voice.lpv: "),
            std::string::npos);
}

/// `good` with the float at file offset `at` set to `value` and the checksum made right again.
std::vector<std::uint8_t> with_float(const std::vector<std::uint8_t>& good, std::size_t at, float value) {
  return rewritten(good, [&](auto& b) {
    const auto bits = std::bit_cast<std::uint32_t>(value);
    for (std::size_t i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(bits >> (8 * i));
  });
}

// Values behind a good checksum that no training produces: a feature mean of 1e38 made every
// `lipdrive process --voice` row read about 1e36.
TEST(VoiceModelFormat, AValueNoTrainingProducesIsAnErrorNamingTheFile) {
  const std::vector<std::uint8_t> good = serialize_voice_model(small_trained_model());
  EXPECT_EQ(format_error(good), "") << "a trained model is within every bound";
  // The feature means follow 18 four-byte fields, the fifth the cepstra: the features' dimensions.
  const std::size_t means = kVoiceHeaderSize + 18 * 4, dims = good[kVoiceHeaderSize + 4 * 4];
  const std::string why = ": no training produces that";
  EXPECT_EQ(format_error(with_float(good, means + 7 * 4, 1e38f)),
            "voice.lpv: feature mean[7] is 1e+38, beyond ±200" + why);
  EXPECT_EQ(format_error(with_float(good, means + dims * 4, 1e-9f)),
            "voice.lpv: feature scale 1e-09 is below 1e-07" + why);
  EXPECT_EQ(format_error(with_float(good, means + 2 * dims * 4, -1e8f)),
            "voice.lpv: hidden weights[0, 0] is -1e+08, beyond ±1e+07" + why);
  // The file ends with centre, gain and rest (4 each), the smoothing and the gate time.
  EXPECT_EQ(format_error(with_float(good, good.size() - 10 * 4, 100)), "voice.lpv: a gain outside 0.25..4" + why);
  EXPECT_EQ(format_error(with_float(good, good.size() - 6 * 4, 50)), "voice.lpv: rest[0] is 50, beyond ±10" + why);
}

// ---- the metric ---------------------------------------------------------------------------

TEST(SpeechAgreement, ScoresOnlySpeechFramesAndTheRestAgainstTheRange) {
  const std::vector<double> truth{0, 0, 1, 2, 3, 2, 1, 0.1, 0.1, 0.1};
  const std::vector<double> voice{5, 5, 2, 4, 6, 4, 2, 0.4, 0.4, std::nan("")};
  const std::vector<bool> speech{false, false, true, true, true, true, true, false, false, false};
  const SpeechAgreement a = speech_agreement(truth, voice, speech, 7, 9);
  EXPECT_EQ(a.speech_frames, 5);
  EXPECT_NEAR(a.pearson_r, 1.0, 1e-12) << "the silent frames' disagreement does not count";
  EXPECT_NEAR(a.std_ratio, 2.0, 1e-12);
  EXPECT_NEAR(a.silence_distance, 0.3 / 3.0, 1e-12) << "|0.4 - 0.1| over the range 3";
  EXPECT_TRUE(std::isnan(speech_agreement(truth, voice, speech, 10, 9).silence_distance));
}

}  // namespace
}  // namespace lipdrive
