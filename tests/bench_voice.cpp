// Per-block cost of the voice path (docs/voice.md): one 10 ms block of 16 kHz sound through
// aubio's features (AudioFeatures::push) and the voice model (VoicePredictor::push), with the
// default model's shape (20 MFCCs, 200 ms back + 40 ms ahead every other frame, 32 hidden
// units) and weights trained on synthetic speech. Besides Google
// Benchmark's mean, the median and p99 of single calls (counters median_us, p99_us; the
// calling thread's CPU time, so other processes on a shared machine do not count).
#include "core/statistics.hpp"
#include "core/voice_training.hpp"

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <array>
#include <cmath>
#include <ctime>
#include <numbers>
#include <random>
#include <span>

namespace lipdrive {
namespace {

std::vector<float> buzz(double seconds, unsigned seed) {
  std::mt19937 random(seed);
  std::normal_distribution<double> noise(0, 1);
  std::vector<float> s(static_cast<std::size_t>(seconds * 16000));
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double t = static_cast<double>(i) / 16000;
    const double open = 0.5 + 0.5 * std::sin(2 * std::numbers::pi * 3 * t);
    s[i] = static_cast<float>(0.2 * open * std::sin(2 * std::numbers::pi * (120 + 50 * open) * t) + 0.001 * noise(random));
  }
  return s;
}

VoiceModel default_shaped_model() {
  std::vector<VoiceRecording> recordings;
  for (unsigned seed = 1; seed <= 2; ++seed) {
    VoiceRecording r;
    r.sample_rate = 16000;
    r.samples = buzz(3, seed);
    for (int f = 0; f < 75; ++f) {
      const double t = f / 25.0;
      const float open = static_cast<float>(0.5 + 0.5 * std::sin(2 * std::numbers::pi * 3 * t));
      r.targets.push_back({t, {open, 1.3f, 0.0f, 0.2f}, true, f % 10 != 0});
    }
    recordings.push_back(r);
  }
  VoiceTrainingSettings settings;  // the defaults: the shape the daemon runs
  settings.epochs = 5;
  return train_voice_model(recordings, settings);
}

double thread_cpu_us() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e6 + static_cast<double>(t.tv_nsec) / 1e3;
}

void BM_VoiceBlock(benchmark::State& state) {
  static const VoiceModel model = default_shaped_model();
  AudioFeatures features(model.features);
  VoicePredictor predictor(model);
  std::array<FeatureFrame, 2> frames{};
  VoiceOutput out;
  const std::vector<float> sound = buzz(10, 7);
  std::vector<double> us;
  us.reserve(static_cast<std::size_t>(state.max_iterations));
  std::uint64_t n = 0;
  for (auto _ : state) {
    const std::size_t at = (n * 160) % (sound.size() - 160);
    const double start = thread_cpu_us();
    const int made = features.push(std::span(sound).subspan(at, 160), frames);
    for (int f = 0; f < made; ++f) predictor.push(frames[static_cast<std::size_t>(f)], out);
    us.push_back(thread_cpu_us() - start);
    benchmark::DoNotOptimize(out);
    ++n;
  }
  state.SetLabel(fmt::format("{} inputs, {} hidden", model.inputs(), model.hidden()));
  state.counters["median_us"] = median(us);
  state.counters["p99_us"] = quantile(us, 0.99);
}
BENCHMARK(BM_VoiceBlock)->Iterations(3000);

}  // namespace
}  // namespace lipdrive
