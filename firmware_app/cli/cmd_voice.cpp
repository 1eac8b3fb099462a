// `lipdrive voice train` and `lipdrive voice eval`: the per-performer voice model
// (docs/method.md 11, docs/voice.md) learned from the performer's own clips, and
// how well it follows the video on recordings it never saw.
#include "core/audio_rates.hpp"
#include "core/metrics.hpp"
#include "core/voice_training.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/cli/commands.hpp"
#include "firmware_app/cli/options.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/tables/grid_align.hpp"
#include "firmware_app/voice/voice_corpus.hpp"

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <iostream>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The defaults were chosen by cross-validation on the first 40 GRID training clips
// (docs/voice.md): 20 MFCCs, 200 ms of context every other frame, a sample at every feature
// frame (targets interpolated), 32 hidden units, no output smoothing.
struct TrainingOptions {
  int sample_rate = 16000;
  std::vector<double> lookahead_ms{40};
  double past_ms = 200;
  int stride = 2;
  int hidden = 32;
  double ridge = 0.01;
  int cepstra = 20;
  int mel_bands = 40;
  double smoothing_ms = 0;
  double gate_ms = 50;
  int epochs = 300;
  double learning_rate = 0.01;
};

VoiceTrainingSettings settings_for(const TrainingOptions& o, double lookahead_ms) {
  VoiceTrainingSettings s;
  s.features.sample_rate = o.sample_rate;
  s.features.hop = o.sample_rate / 100;
  s.features.cepstra = o.cepstra;
  s.features.mel_bands = o.mel_bands;
  s.features.max_hz = std::min(7600.0f, 0.475f * static_cast<float>(o.sample_rate));
  const double frame_ms = 1000.0 * s.features.hop / o.sample_rate;
  s.context.stride = o.stride;
  s.context.past = static_cast<int>(std::lround(o.past_ms / frame_ms));
  s.context.lookahead = static_cast<int>(std::lround(lookahead_ms / frame_ms));
  s.hidden = o.hidden;
  s.ridge = o.ridge;
  s.smoothing_s = static_cast<float>(o.smoothing_ms / 1000);
  s.gate_s = static_cast<float>(o.gate_ms / 1000);
  s.epochs = o.epochs;
  s.learning_rate = o.learning_rate;
  return s;
}

void add_training_options(CLI::App* cmd, TrainingOptions& o, bool sweep) {
  cmd->add_option("--sample-rate", o.sample_rate, "the sound is resampled to this (Hz); the live input must match")
      ->check(CLI::Range(kMinAudioSampleRate, kMaxVoiceSampleRate))
      ->capture_default_str();
  auto* lookahead = cmd->add_option("--lookahead-ms", o.lookahead_ms,
                                    sweep ? "look-ahead(s) in ms, 0..80; several: one model each (a sweep)"
                                          : "look-ahead in ms, 0..80: the delay it costs, for accuracy")
                        ->check(finite_range(0.0, 80.0))
                        ->capture_default_str();
  if (!sweep) lookahead->expected(1);
  cmd->add_option("--past-ms", o.past_ms, "context before each prediction, ms")
      ->check(finite_range(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--stride", o.stride, "every Nth feature frame of the context")
      ->check(CLI::Range(1, 10))
      ->capture_default_str();
  cmd->add_option("--hidden", o.hidden, "tanh hidden units (0: linear ridge regression)")
      ->check(CLI::Range(0, kMaxVoiceHidden))
      ->capture_default_str();
  cmd->add_option("--ridge", o.ridge, "L2 penalty per sample")->check(finite_range(0.0, 1e6))->capture_default_str();
  cmd->add_option("--cepstra", o.cepstra, "MFCCs per frame (0: the log mel band energies)")
      ->check(CLI::Range(0, 64))
      ->capture_default_str();
  cmd->add_option("--mel-bands", o.mel_bands, "mel filter bank bands")->check(CLI::Range(4, 64))->capture_default_str();
  cmd->add_option("--smoothing-ms", o.smoothing_ms, "output low-pass time constant, ms")
      ->check(finite_range(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--gate-ms", o.gate_ms, "cross-fade to and from rest on voice activity, ms")
      ->check(finite_range(0.0, 1000.0))
      ->capture_default_str();
  cmd->add_option("--epochs", o.epochs, "hidden layer: training steps")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd->add_option("--learning-rate", o.learning_rate, "hidden layer: Adam's step size")
      ->check(finite_range(1e-6, 1.0))
      ->capture_default_str();
}

std::vector<VoiceRecording> load_all(const std::vector<fs::path>& inputs, const fs::path& config_file,
                                     int sample_rate) {
  Config config;  // the defaults
  if (!config_file.empty()) config = load_config(config_file, ConfigUse::kOffline);
  const std::unique_ptr<FrameProcessor> processor = make_processor(config, load_performer(config));
  std::vector<VoiceRecording> recordings;
  for (const fs::path& input : inputs) recordings.push_back(load_voice_recording(input, sample_rate, *processor));
  return recordings;
}

VoiceModel train(const std::vector<VoiceRecording>& recordings, const VoiceTrainingSettings& settings) {
  try {
    return train_voice_model(recordings, settings);
  } catch (const std::invalid_argument& e) {
    throw CommandError(e.what(), kExitDataError);
  }
}

/// One recording's agreement per target, and the final silence of `open`.
struct Scores {
  std::string name;
  std::array<SpeechAgreement, kNumVoiceTargets> targets{};
};

/// `recording` (a copy: without a transcript its speech frames are marked here, by the voice
/// activity, as training marks them) scored against `model`'s predictions.
Scores score(const VoiceModel& model, VoiceRecording recording) {
  if (!recording.has_transcript)
    mark_voice_activity(recording, model.features, model.activity, extract_features(model.features, recording.samples));
  const std::vector<VoiceOutput> outputs = predict_recording(model, recording);
  const std::size_t n = recording.targets.size();
  std::vector<bool> speech(n);
  for (std::size_t i = 0; i < n; ++i) speech[i] = recording.targets[i].speech;
  // The final silence: from 0.12 s into the last silent stretch to the end (docs/method.md 5;
  // a millisecond's allowance for the frames' rounded times).
  int first = static_cast<int>(n), last = static_cast<int>(n) - 1;
  while (first > 0 && !speech[static_cast<std::size_t>(first - 1)]) --first;
  if (first == static_cast<int>(n) || first == 0) {
    first = last + 1;  // no speech or no final silence
  } else {
    const double begins_s = recording.targets[static_cast<std::size_t>(first)].time_s;
    while (first <= last &&
           recording.targets[static_cast<std::size_t>(first)].time_s < begins_s + ClosureMetric::kSilenceDelay_s - 1e-3)
      ++first;
  }
  Scores s;
  s.name = recording.name;
  for (std::size_t k = 0; k < kNumVoiceTargets; ++k) {
    std::vector<double> truth(n), voice(n);
    for (std::size_t i = 0; i < n; ++i) {
      truth[i] = recording.targets[i].tracked ? recording.targets[i].values[k] : kNaN;
      voice[i] = outputs[i].values[k];
    }
    s.targets[k] = speech_agreement(truth, voice, speech, first, last);
  }
  return s;
}

double mean_finite(const std::vector<double>& values) {
  double sum = 0;
  int count = 0;
  for (double v : values)
    if (std::isfinite(v)) {
      sum += v;
      ++count;
    }
  return count > 0 ? sum / count : kNaN;
}

/// Per target: mean r, mean σ ratio; mean final-silence distance of open.
nlohmann::json summary(const std::vector<Scores>& scores) {
  nlohmann::json out;
  for (std::size_t k = 0; k < kNumVoiceTargets; ++k) {
    std::vector<double> r, ratio, silence;
    for (const Scores& s : scores) {
      r.push_back(s.targets[k].pearson_r);
      ratio.push_back(s.targets[k].std_ratio);
      silence.push_back(s.targets[k].silence_distance);
    }
    out[std::string(voice_target_name(static_cast<VoiceTarget>(k)))] = {
        {"r", mean_finite(r)}, {"std_ratio", mean_finite(ratio)}, {"silence_distance", mean_finite(silence)}};
  }
  out["recordings"] = scores.size();
  return out;
}

void print_scores(const std::vector<Scores>& scores, const std::string& title) {
  fmt::print("{}\n{:<40} {:>6} {:>7} {:>7} {:>7} {:>7} {:>7} {:>8}\n", title, "recording", "frames", "open r", "sd",
             "silence", "width r", "prot r", "seal r");
  for (const Scores& s : scores) {
    const auto& t = s.targets;
    fmt::print("{:<40} {:>6} {:>7.3f} {:>7.2f} {:>7.3f} {:>7.3f} {:>7.3f} {:>8.3f}\n",
               fs::path(s.name).filename().string(), t[0].speech_frames, t[0].pearson_r, t[0].std_ratio,
               t[0].silence_distance, t[1].pearson_r, t[2].pearson_r, t[3].pearson_r);
  }
  const nlohmann::json m = summary(scores);
  fmt::print("{:<40} {:>6} {:>7.3f} {:>7.2f} {:>7.3f} {:>7.3f} {:>7.3f} {:>8.3f}\n", "mean", "",
             m["open"]["r"].get<double>(), m["open"]["std_ratio"].get<double>(),
             m["open"]["silence_distance"].get<double>(), m["width"]["r"].get<double>(),
             m["protrusion"]["r"].get<double>(), m["seal"]["r"].get<double>());
  fmt::print("std ratio: width {:.2f}, protrusion {:.2f}, seal {:.2f}\n", m["width"]["std_ratio"].get<double>(),
             m["protrusion"]["std_ratio"].get<double>(), m["seal"]["std_ratio"].get<double>());
}

struct TrainCommand {
  std::vector<fs::path> inputs;
  fs::path out;
  fs::path config;
  TrainingOptions training;
};

void run_train(const TrainCommand& c) {
  const std::vector<VoiceRecording> recordings = load_all(c.inputs, c.config, c.training.sample_rate);
  const VoiceModel model = train(recordings, settings_for(c.training, c.training.lookahead_ms.front()));
  save_voice_model_file(c.out, model);
  std::size_t tracked = 0;
  double seconds = 0;
  for (const VoiceRecording& r : recordings) {
    seconds += static_cast<double>(r.samples.size()) / r.sample_rate;
    for (const VoiceTargetFrame& t : r.targets) tracked += t.tracked;
  }
  fmt::print("{}: {} recordings, {:.1f} s of sound, {} tracked frames; delay {:.0f} ms (look-ahead {:.0f} ms)\n",
             c.out.string(), recordings.size(), seconds, tracked, model.delay_s() * 1000,
             model.context.lookahead * 1000.0 * model.features.hop / model.features.sample_rate);
}

struct EvalCommand {
  fs::path voice;
  std::vector<fs::path> train, test;
  int folds = 0;
  fs::path config;
  bool json = false;
  TrainingOptions training;
};

void run_eval(const EvalCommand& c) {
  if (!c.voice.empty() == !c.train.empty())
    throw CLI::ValidationError("--voice / --train",
                               "give either a trained model (--voice) or material to train on (--train)");
  if (!c.voice.empty() && c.folds > 0)
    throw CLI::ValidationError("--folds", "cross-validates --train; a --voice model is trained already");
  if (!c.voice.empty() && c.test.empty())
    throw CLI::ValidationError("--test",
                               "recordings to evaluate the --voice model on (--folds cross-validates --train)");
  if (c.folds == 0 && c.test.empty())
    throw CLI::ValidationError("--test", "recordings to evaluate on (or --folds K to cross-validate --train)");
  // A fold past the recordings holds none out: it would train a model for nothing.
  if (!c.train.empty() && static_cast<std::size_t>(c.folds) > c.train.size())
    throw CLI::ValidationError("--folds", fmt::format("{} exceeds the {} recordings of --train (one held out per fold)",
                                                      c.folds, c.train.size()));
  nlohmann::json report;
  if (!c.voice.empty()) {
    const VoiceModel model = load_voice_model_file(c.voice);
    const std::vector<VoiceRecording> test = load_all(c.test, c.config, model.features.sample_rate);
    std::vector<Scores> scores;
    for (const VoiceRecording& r : test) scores.push_back(score(model, r));
    if (!c.json) print_scores(scores, fmt::format("{} (delay {:.0f} ms)", c.voice.string(), model.delay_s() * 1000));
    report["test"] = summary(scores);
  } else {
    const std::vector<VoiceRecording> train_set = load_all(c.train, c.config, c.training.sample_rate);
    const std::vector<VoiceRecording> test_set =
        c.test.empty() ? std::vector<VoiceRecording>{} : load_all(c.test, c.config, c.training.sample_rate);
    for (const double lookahead : c.training.lookahead_ms) {
      const VoiceTrainingSettings settings = settings_for(c.training, lookahead);
      nlohmann::json entry;
      entry["lookahead_ms"] = lookahead;
      if (c.folds > 0) {
        // Folds by recording, in the order given: recording i is held out in fold i mod K.
        std::vector<Scores> scores;
        for (int fold = 0; fold < c.folds; ++fold) {
          std::vector<VoiceRecording> train_part, held_out;
          for (std::size_t i = 0; i < train_set.size(); ++i)
            (static_cast<int>(i) % c.folds == fold ? held_out : train_part).push_back(train_set[i]);
          const VoiceModel model = train(train_part, settings);
          for (const VoiceRecording& r : held_out) scores.push_back(score(model, r));
          entry["delay_ms"] = model.delay_s() * 1000;
        }
        if (!c.json)
          print_scores(scores, fmt::format("cross-validation, {} folds, look-ahead {} ms", c.folds, lookahead));
        entry["cross_validation"] = summary(scores);
      }
      if (!test_set.empty()) {
        const VoiceModel model = train(train_set, settings);
        std::vector<Scores> scores;
        for (const VoiceRecording& r : test_set) scores.push_back(score(model, r));
        if (!c.json)
          print_scores(scores,
                       fmt::format("test, look-ahead {} ms (delay {:.0f} ms)", lookahead, model.delay_s() * 1000));
        entry["delay_ms"] = model.delay_s() * 1000;
        entry["test"] = summary(scores);
      }
      report["runs"].push_back(entry);
    }
  }
  if (c.json) fmt::print("{}\n", report.dump(2));
}

}  // namespace

void add_voice_command(CLI::App& app) {
  CLI::App* voice = app.add_subcommand("voice", "The performer's voice model: train it, evaluate it");
  voice->require_subcommand(1);

  auto train = std::make_shared<TrainCommand>();
  CLI::App* t = voice->add_subcommand("train",
                                      "Learn a voice model (.lpv) from clips with sound (their video tracked) or the "
                                      "daemon's takes (NAME.csv with its sound NAME.wav)");
  t->add_option("INPUT", train->inputs, "clips with sound (the video is tracked), or takes (.csv) with their sound")
      ->required();
  t->add_option("--out", train->out, "the voice model file to write (.lpv)")->required();
  t->add_option("--config", train->config,
                "the daemon's configuration: the tracker and fit the clips are measured with");
  add_training_options(t, train->training, false);
  t->callback([train, t] {
    refuse_out_over_input(*t);
    run_train(*train);
  });

  auto eval = std::make_shared<EvalCommand>();
  CLI::App* e = voice->add_subcommand(
      "eval", "How a voice model follows the video on recordings it did not learn from (r, std ratio, rest)");
  e->add_option("--voice", eval->voice, "a trained voice model (.lpv) to evaluate");
  e->add_option("--train", eval->train, "recordings to train on (with the training options)");
  e->add_option("--test", eval->test, "recordings to evaluate on");
  e->add_option("--folds", eval->folds, "cross-validate on --train: K folds by recording (recording i in fold i mod K)")
      ->check(CLI::Range(2, 100));
  e->add_option("--config", eval->config,
                "the daemon's configuration: the tracker and fit the clips are measured with");
  e->add_flag("--json", eval->json, "print the figures as JSON");
  add_training_options(e, eval->training, true);
  e->callback([eval] { run_eval(*eval); });
}

}  // namespace lipdrive
