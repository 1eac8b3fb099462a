// SMPTE timecode: the label arithmetic of core/timecode (drop-frame across minute
// boundaries, every frame of a day at every rate), and LTC audio from libltc's encoder
// decoded back with the frame start times the encoder used.
#include "allocation_counter.hpp"
#include "core/timecode.hpp"
#include "drivers/clock.hpp"
#include "drivers/ltc_decoder.hpp"
#include "firmware_app/daemon/timecode_source.hpp"
#include "sim/ltc_generator.hpp"

#include <gtest/gtest.h>
#include <ltc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <random>
#include <thread>
#include <vector>

namespace lipdrive {
namespace {

constexpr std::array kRates{TimecodeRate::k24, TimecodeRate::k25, TimecodeRate::k29_97DropFrame, TimecodeRate::k30};

std::string label(std::int64_t frame, TimecodeRate rate) { return std::string(format_frame(frame, rate).view()); }

std::int32_t frame_of(std::string_view text, TimecodeRate rate) {
  const auto parsed = parse_timecode(text);
  EXPECT_TRUE(parsed) << text;
  const auto frame = parsed ? frame_from_timecode(*parsed, rate) : std::nullopt;
  EXPECT_TRUE(frame) << text;
  return frame.value_or(-1);
}

TEST(Timecode, DropFrameSkipsTwoNumbersAtEveryMinuteButTheTenth) {
  const auto df = TimecodeRate::k29_97DropFrame;
  // Minute 0 -> 1: ;00 and ;01 do not exist.
  const std::int32_t last_of_first_minute = frame_of("00:00:59;29", df);
  EXPECT_EQ(last_of_first_minute, 1799);
  EXPECT_EQ(label(last_of_first_minute + 1, df), "00:01:00;02");
  EXPECT_FALSE(frame_from_timecode({0, 1, 0, 0}, df));
  EXPECT_FALSE(frame_from_timecode({0, 1, 0, 1}, df));
  EXPECT_TRUE(frame_from_timecode({0, 1, 0, 2}, df));
  // Minute 9 -> 10: nothing is dropped at the tenth minute.
  const std::int32_t before_ten = frame_of("00:09:59;29", df);
  EXPECT_EQ(label(before_ten + 1, df), "00:10:00;00");
  EXPECT_EQ(label(before_ten + 2, df), "00:10:00;01");
  EXPECT_EQ(label(before_ten + 3, df), "00:10:00;02");
  EXPECT_EQ(frame_of("00:10:00;00", df), 17982);
  // An hour of labels is 107892 frames (108 numbers dropped), which take 3599.9964 s at
  // 30000/1001 fps: the labels run 3.6 ms per hour ahead of the clock.
  EXPECT_EQ(frame_of("01:00:00;00", df), 107892);
  EXPECT_EQ(frame_start_ns(107892, df), 3'599'996'400'000);
  // Minute 10 -> 11 drops again.
  EXPECT_EQ(label(frame_of("00:10:59;29", df) + 1, df), "00:11:00;02");
  EXPECT_EQ(frames_per_day(df), 2'589'408);
}

TEST(Timecode, EveryFrameOfADayRoundTripsAndCountsUp) {
  for (const TimecodeRate rate : kRates) {
    const int fps = label_fps(rate);
    Timecode previous = timecode_from_frame(frames_per_day(rate) - 1, rate);
    EXPECT_EQ(previous, (Timecode{23, 59, 59, fps - 1})) << rate_name(rate);
    for (std::int32_t frame = 0; frame < frames_per_day(rate); ++frame) {
      const Timecode t = timecode_from_frame(frame, rate);
      ASSERT_EQ(frame_from_timecode(t, rate), frame) << rate_name(rate) << " " << label(frame, rate);
      // The next label of the previous one, with drop-frame's skips.
      Timecode next = previous;
      if (++next.frames == fps) {
        next.frames = 0;
        if (++next.seconds == 60) {
          next.seconds = 0;
          if (++next.minutes == 60) {
            next.minutes = 0;
            next.hours = (next.hours + 1) % 24;
          }
          if (is_drop_frame(rate) && next.minutes % 10 != 0) next.frames = 2;
        }
      }
      ASSERT_EQ(t, next) << rate_name(rate) << " after " << std::string(format_timecode(previous, rate).view());
      previous = t;
    }
  }
}

TEST(Timecode, ParsesFormatsAndRejects) {
  EXPECT_EQ(parse_timecode("10:20:30:12"), (Timecode{10, 20, 30, 12}));
  EXPECT_EQ(parse_timecode("10:20:30;12"), (Timecode{10, 20, 30, 12}));
  EXPECT_EQ(parse_timecode("10:20:30.12"), (Timecode{10, 20, 30, 12}));
  EXPECT_FALSE(parse_timecode("10:20:30"));
  EXPECT_FALSE(parse_timecode("1:20:30:12x"));
  EXPECT_FALSE(parse_timecode("10-20-30-12"));
  EXPECT_FALSE(frame_from_timecode({24, 0, 0, 0}, TimecodeRate::k25));
  EXPECT_FALSE(frame_from_timecode({0, 60, 0, 0}, TimecodeRate::k25));
  EXPECT_FALSE(frame_from_timecode({0, 0, 0, 25}, TimecodeRate::k25));
  EXPECT_TRUE(frame_from_timecode({0, 0, 0, 29}, TimecodeRate::k30));
  EXPECT_FALSE(frame_from_timecode({0, 0, 0, 24}, TimecodeRate::k24));
  EXPECT_EQ(label(0, TimecodeRate::k29_97DropFrame), "00:00:00;00");
  EXPECT_EQ(label(-1, TimecodeRate::k25), "23:59:59:24");
  EXPECT_EQ(label(25 * 3600 * 24 + 3, TimecodeRate::k25), "00:00:00:03");
  EXPECT_EQ(rate_from_fps(29.97), TimecodeRate::k29_97DropFrame);
  EXPECT_EQ(rate_from_fps(24), TimecodeRate::k24);
  EXPECT_FALSE(rate_from_fps(50));
}

TEST(Timecode, MomentsFallInTheRightFrame) {
  const auto r25 = TimecodeRate::k25;
  EXPECT_EQ(frame_after(100, 0, r25), 100);
  EXPECT_EQ(frame_after(100, 39'999'999, r25), 100);
  EXPECT_EQ(frame_after(100, 40'000'000, r25), 101);
  EXPECT_EQ(frame_after(100, -1, r25), 99);
  EXPECT_EQ(frame_after(0, -1, r25), frames_per_day(r25) - 1);
  // 29.97: frame n starts at n · 1001 / 30000 s.
  const auto df = TimecodeRate::k29_97DropFrame;
  EXPECT_EQ(frame_after(0, frame_start_ns(30000, df), df), 30000);
  EXPECT_EQ(frame_after(0, frame_start_ns(30000, df) - 1, df), 29999);
  // Time of day: 13:45:10.5 at 25 fps is 13:45:10:12.
  const std::int64_t ns = ((13LL * 60 + 45) * 60 + 10) * 1'000'000'000 + 500'000'000;
  EXPECT_EQ(label(frame_after(0, ns, r25), r25), "13:45:10:12");
}

/// Encodes `count` frames from `start` and decodes them in blocks of `block` samples; checks
/// every decoded label and that its start time is the sample the encoder began it at.
void round_trip(TimecodeRate rate, std::string_view start, int count, std::size_t block) {
  constexpr int kRate = 48000;
  LtcGenerator generator(kRate, rate, frame_of(start, rate));
  std::vector<float> audio;
  std::vector<std::int64_t> starts;
  std::vector<std::int32_t> frames;
  for (int i = 0; i < count; ++i) {
    starts.push_back(static_cast<std::int64_t>(audio.size()));
    frames.push_back(generator.frame());
    const auto samples = generator.next_frame();
    audio.insert(audio.end(), samples.begin(), samples.end());
  }
  LtcDecoder decoder(kRate, frame_rate(rate).fps());
  const std::int64_t t0 = 5'000'000'000;  // the stream's first sample, any monotonic time
  std::size_t decoded = 0;
  for (std::size_t begin = 0; begin < audio.size(); begin += block) {
    const std::size_t size = std::min(block, audio.size() - begin);
    decoder.write(std::span<const float>(audio).subspan(begin, size), kRate,
                  t0 + static_cast<std::int64_t>(begin) * 1'000'000'000 / kRate);
    for (LtcFrame f; decoder.read(f);) {
      const Timecode t{f.hours, f.minutes, f.seconds, f.frames};
      const auto number = frame_from_timecode(t, rate);
      ASSERT_TRUE(number) << std::string(format_timecode(t, rate).view());
      const auto at = std::ranges::find(frames, *number);
      ASSERT_NE(at, frames.end()) << "decoded a frame that was never encoded";
      const std::int64_t expected_ns = t0 + starts[at - frames.begin()] * 1'000'000'000 / kRate;
      // libltc places a frame's start to within a few samples.
      EXPECT_NEAR(static_cast<double>(f.start_time_ns - expected_ns), 0.0, 3 * 1e9 / kRate)
          << rate_name(rate) << ": start of " << std::string(format_timecode(t, rate).view());
      EXPECT_EQ(f.drop_frame, is_drop_frame(rate));
      EXPECT_FALSE(f.reverse);
      ++decoded;
    }
  }
  // libltc needs the first frame to lock on.
  EXPECT_GE(decoded, static_cast<std::size_t>(count - 2)) << rate_name(rate);
}

TEST(Ltc, DecodesEveryEncodedFrameWithItsStartTime) {
  round_trip(TimecodeRate::k25, "09:59:58:00", 100, 480);
  round_trip(TimecodeRate::k24, "00:00:00:00", 60, 1024);
  round_trip(TimecodeRate::k30, "23:59:59:00", 60, 333);
}

TEST(Ltc, DropFrameAcrossMinuteBoundaries) {
  // 00:00:59;20 .. 00:01:01: crosses a dropping minute; 00:09:59;20 crosses the tenth.
  round_trip(TimecodeRate::k29_97DropFrame, "00:00:59;20", 60, 480);
  round_trip(TimecodeRate::k29_97DropFrame, "00:09:59;20", 60, 480);
}

TEST(Ltc, DecodingAndStampingAllocateNothing) {
  LtcGenerator generator(48000, TimecodeRate::k25, 0);
  std::vector<float> audio;
  for (int i = 0; i < 50; ++i) {
    const auto frame = generator.next_frame();
    audio.insert(audio.end(), frame.begin(), frame.end());
  }
  LtcDecoder decoder(48000, 25);
  int frames = 0;
  std::int32_t stamped = 0;
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  for (std::size_t begin = 0; begin + 480 <= audio.size(); begin += 480) {
    decoder.write(std::span<const float>(audio).subspan(begin, 480), 48000, static_cast<std::int64_t>(begin) * 20'833);
    for (LtcFrame f; decoder.read(f);) {
      ++frames;
      stamped = frame_after(frame_from_timecode({f.hours, f.minutes, f.seconds, f.frames}, TimecodeRate::k25).value(),
                            12'345'678, TimecodeRate::k25);
      format_frame(stamped, TimecodeRate::k25);
    }
  }
  const long allocations = test::allocation_count() - before;
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocations, 0);
  EXPECT_GE(frames, 45);
  EXPECT_GT(stamped, 0);
}

TEST(Ltc, NoiseAndSilenceDecodeToNothing) {
  LtcDecoder decoder(48000, 25);
  std::vector<float> audio(48000 * 3);
  std::minstd_rand random(7);
  std::uniform_real_distribution<float> noise(-0.5f, 0.5f);
  for (float& sample : audio) sample = noise(random);
  std::vector<float> silence(48000, 0.0f);
  int frames = 0;
  for (const auto* signal : {&audio, &silence}) {
    decoder.write(*signal, 48000, 0);
    for (LtcFrame f; decoder.read(f);) ++frames;
  }
  EXPECT_EQ(frames, 0);
}

TEST(Ltc, SimulatedInputPlaysInRealTimeOnTheMonotonicClock) {
  SimulatedLtcAudio audio({.sample_rate = 48000,
                           .rate = TimecodeRate::k25,
                           .start = {10, 0, 0, 0},
                           .signal = SimulatedLtcSignal::kLtc,
                           .block_frames = 480});
  LtcDecoder decoder(48000, 25);
  std::vector<LtcFrame> frames;
  std::int64_t previous_end = 0;
  const auto begin = std::chrono::steady_clock::now();
  for (int i = 0; i < 50; ++i) {  // half a second
    AudioBlock block;
    ASSERT_EQ(audio.read(block, std::chrono::milliseconds(100)), AudioStatus::kBlock);
    ASSERT_EQ(block.frames, 480);
    if (previous_end != 0) {
      EXPECT_EQ(block.capture_time_ns, previous_end) << "blocks follow the sample clock";
    }
    previous_end = block.capture_time_ns + 480 * 1'000'000'000LL / 48000;
    decoder.write({block.samples.data(), static_cast<std::size_t>(block.frames)}, block.sample_rate,
                  block.capture_time_ns);
    for (LtcFrame f; decoder.read(f);) frames.push_back(f);
  }
  EXPECT_GE(std::chrono::steady_clock::now() - begin, std::chrono::milliseconds(480)) << "paced like a sound card";
  ASSERT_GE(frames.size(), 10u);
  for (const LtcFrame& f : frames) {
    const std::int32_t n = frame_from_timecode({f.hours, f.minutes, f.seconds, f.frames}, TimecodeRate::k25).value();
    const std::int64_t expected =
        audio.start_time_ns() + (n - frame_of("10:00:00:00", TimecodeRate::k25)) * 40'000'000LL;
    EXPECT_NEAR(static_cast<double>(f.start_time_ns - expected), 0.0, 50'000.0);
  }
}

/// An LTC timecode source on the simulated input, and the input (owned by the source).
struct LtcOnSimulatedInput {
  explicit LtcOnSimulatedInput(SimulatedLtcOptions options, TimecodeRate configured) {
    auto audio = std::make_unique<SimulatedLtcAudio>(options);
    input = audio.get();
    source = std::make_unique<LtcTimecode>(std::move(audio), configured);
  }
  SimulatedLtcAudio* input = nullptr;
  std::unique_ptr<LtcTimecode> source;
};

TEST(LtcTimecode, StampsCaptureTimesWithTheFramesTheEncoderPlayedThen) {
  for (const TimecodeRate rate : {TimecodeRate::k25, TimecodeRate::k29_97DropFrame}) {
    const Timecode start = rate == TimecodeRate::k25 ? Timecode{9, 59, 59, 0} : Timecode{0, 0, 59, 10};
    LtcOnSimulatedInput ltc({.sample_rate = 48000, .rate = rate, .start = start}, rate);
    std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // crosses 10:00:00:00 / 00:01:00;02
    const std::int64_t start_ns = ltc.input->start_time_ns();
    ASSERT_GT(start_ns, 0);
    const std::int32_t first = frame_from_timecode(start, rate).value();
    const FrameRate r = frame_rate(rate);
    // Every 0.7 ms of the last 400 (a step that does not divide the frame period): the frame
    // the encoder was playing at that moment.
    const std::int64_t now = monotonic_ns();
    int checked = 0, near_boundary = 0;
    for (std::int64_t t = now - 400'000'000; t < now; t += 700'000) {
      const auto stamped = ltc.source->frame_at(t);
      ASSERT_TRUE(stamped) << rate_name(rate) << ": LTC present";
      const double position = static_cast<double>(t - start_ns) * static_cast<double>(r.numerator) /
                              (1e9 * static_cast<double>(r.denominator));
      const std::int32_t expected = frame_after(first, t - start_ns, rate);
      // libltc places a frame's start to within a few samples (0.1 ms).
      const double from_boundary = std::abs(position - std::round(position)) / r.fps();
      if (from_boundary < 1e-4) {
        ++near_boundary;
        continue;
      }
      EXPECT_EQ(*stamped, expected) << rate_name(rate) << " at " << (t - start_ns) / 1e6
                                    << " ms: " << label(*stamped, rate) << " instead of " << label(expected, rate);
      ++checked;
    }
    EXPECT_GT(checked, 550);
    EXPECT_LT(near_boundary, 20);
    EXPECT_EQ(ltc.source->problem(), "");
    EXPECT_EQ(ltc.source->frames_rejected(), 0u);
    EXPECT_GT(ltc.source->frames_decoded(), 30u);
  }
}

TEST(LtcTimecode, AbsentOrGarbledLtcStampsNothingAndSaysWhy) {
  {
    LtcOnSimulatedInput silent({.signal = SimulatedLtcSignal::kSilence}, TimecodeRate::k25);
    LtcOnSimulatedInput noise({.signal = SimulatedLtcSignal::kNoise}, TimecodeRate::k25);
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
    for (const auto* ltc : {&silent, &noise}) {
      EXPECT_FALSE(ltc->source->frame_at(monotonic_ns()));
      EXPECT_NE(ltc->source->problem().find("no LTC on sim:"), std::string::npos) << ltc->source->problem();
    }
  }
  // 29.97 drop-frame LTC where 30 fps is configured: every frame carries the wrong flag.
  LtcOnSimulatedInput wrong_rate({.rate = TimecodeRate::k29_97DropFrame}, TimecodeRate::k30);
  std::this_thread::sleep_for(std::chrono::milliseconds(700));
  EXPECT_FALSE(wrong_rate.source->frame_at(monotonic_ns()));
  EXPECT_GT(wrong_rate.source->frames_rejected(), 10u);
  EXPECT_NE(wrong_rate.source->problem().find("LTC garbled"), std::string::npos) << wrong_rate.source->problem();
}

TEST(ClockTimecode, TimeOfDayCountsUpWithTheClock) {
  const ClockTimecode clock(TimecodeRate::k25);
  const std::time_t now = std::time(nullptr);
  std::tm local{};
  ::localtime_r(&now, &local);
  const std::int32_t frame = clock.frame_at(monotonic_ns()).value();
  const Timecode t = timecode_from_frame(frame, TimecodeRate::k25);
  const int seconds_of_day = local.tm_hour * 3600 + local.tm_min * 60 + local.tm_sec;
  EXPECT_NEAR(t.hours * 3600 + t.minutes * 60 + t.seconds, seconds_of_day, 1);
  std::int32_t previous = -1;
  for (int i = 0; i < 200; ++i) {
    const std::int32_t f = clock.frame_at(monotonic_ns()).value();
    EXPECT_GE(f, previous) << "monotonic (away from midnight)";
    previous = f;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_GE(previous - frame, 9) << "0.4 s at 25 fps";
}

}  // namespace
}  // namespace lipdrive
