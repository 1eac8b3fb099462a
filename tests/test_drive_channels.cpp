// The safety layer of the drive (docs/data-flow.md): mapping, clamp, slew limit, fail-safe ease;
// the hand-over between the face and the voice (docs/voice.md).
#include "allocation_counter.hpp"
#include "core/calibration.hpp"
#include "core/drive_channels.hpp"
#include "core/drive_source.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace lipdrive {
namespace {

constexpr std::int64_t kFrameNs = 16'666'667;  // 60 fps
constexpr std::int64_t kMs = 1'000'000;

ChannelSpec open_channel() {
  return {.name = "jaw", .signal = Signal::kOpen, .out_min = 1000, .out_max = 2000, .neutral = 1200};
}

DriveSignals open_at(float value) {
  DriveSignals s;
  s[Signal::kOpen] = value;
  return s;
}

TEST(DriveSignals, NamesRoundTripAndFollowTheVisemesAndArkitNames) {
  for (int s = 0; s < kNumSignals; ++s)
    EXPECT_EQ(parse_signal(signal_name(static_cast<Signal>(s))), static_cast<Signal>(s));
  EXPECT_EQ(signal_name(Signal::kOpen), "open");
  EXPECT_EQ(signal_name(Signal::kSeal), "seal");
  for (int v = 0; v < kNumVisemes; ++v)
    EXPECT_EQ(signal_name(viseme_signal(v)), "viseme_" + std::string(kVisemeNames[static_cast<std::size_t>(v)]));
  for (int a = 0; a < kNumArkit; ++a)
    EXPECT_EQ(signal_name(arkit_signal(a)), "arkit_" + std::string(kArkitNames[static_cast<std::size_t>(a)]));
  EXPECT_EQ(parse_signal("arkit_jawOpen"), arkit_signal(17));
  EXPECT_FALSE(parse_signal("mouth"));
  EXPECT_FALSE(parse_signal("arkit_"));
  EXPECT_FALSE(parse_signal("jawOpen"));
}

TEST(ChannelMapping, MapsClampsAndInverts) {
  ChannelSpec spec = open_channel();
  spec.in_min = 0.2;
  spec.in_max = 0.6;
  EXPECT_DOUBLE_EQ(map_to_output(spec, 0.4), 1500);
  EXPECT_DOUBLE_EQ(map_to_output(spec, -5), 1000);
  EXPECT_DOUBLE_EQ(map_to_output(spec, 5), 2000);
  spec.invert = true;
  EXPECT_DOUBLE_EQ(map_to_output(spec, 0.2), 2000);
}

TEST(ChannelBank, RejectsImpossibleChannels) {
  ChannelSpec spec = open_channel();
  spec.neutral = 5000;
  EXPECT_THROW(ChannelBank({&spec, 1}, {}), std::invalid_argument);
  spec = open_channel();
  spec.in_max = spec.in_min;
  EXPECT_THROW(ChannelBank({&spec, 1}, {}), std::invalid_argument);
  std::vector<ChannelSpec> too_many(kMaxChannels + 1, open_channel());
  EXPECT_THROW(ChannelBank(too_many, {}), std::invalid_argument);
}

TEST(ChannelBank, StartsNeutralAndEasesInWithoutAJump) {
  const ChannelSpec spec = open_channel();
  ChannelBank bank({&spec, 1}, {.hold_ns = 200 * kMs, .ease_ns = 300 * kMs});
  EXPECT_EQ(bank.values()[0], 1200);
  double previous = 1200;
  std::int64_t now = 0;
  for (int frame = 0; frame < 30; ++frame, now += kFrameNs) {
    const double value = bank.step(open_at(1), {.tracked = true, .now_ns = now})[0];
    // The ease covers 800 units in 300 ms: at most 45 units per 60 fps frame.
    EXPECT_LE(value - previous, 800.0 * kFrameNs / (300 * kMs) + 1e-9) << frame;
    previous = value;
  }
  EXPECT_DOUBLE_EQ(previous, 2000);
  EXPECT_FALSE(bank.fail_safe_active());
}

TEST(ChannelBank, NeverTrackedIsFailSafeFromTheFirstStep) {
  // CLOCK_MONOTONIC on a board that has been up for an hour: there is no tracked frame to hold.
  const ChannelSpec spec = open_channel();
  ChannelBank bank({&spec, 1}, {.hold_ns = 200 * kMs, .ease_ns = 300 * kMs});
  const std::int64_t up_an_hour = 3600 * 1000 * kMs;
  for (std::int64_t now = up_an_hour; now < up_an_hour + 100 * kMs; now += kFrameNs) {
    EXPECT_EQ(bank.step(open_at(1), {.tracked = false, .now_ns = now})[0], 1200);
    EXPECT_TRUE(bank.fail_safe_active()) << "no hold before the face was ever tracked";
  }
}

/// Tracks for a second, then loses the face; returns the frame time at which neutral is reached.
std::int64_t time_to_neutral(ChannelBank& bank, std::int64_t& now) {
  for (; now < 1000 * kMs; now += kFrameNs) bank.step(open_at(0.9f), {.tracked = true, .now_ns = now});
  const std::int64_t lost_at = now;
  for (; now < lost_at + 5000 * kMs; now += kFrameNs) {
    if (bank.step(open_at(0.9f), {.tracked = false, .now_ns = now})[0] == 1200) return now - lost_at;
  }
  return -1;
}

TEST(ChannelBank, LossHoldsThenReachesNeutralWithinHoldPlusEase) {
  const ChannelSpec spec = open_channel();
  const SafetySettings safety{.hold_ns = 250 * kMs, .ease_ns = 500 * kMs};
  ChannelBank bank({&spec, 1}, safety);
  std::int64_t now = 0;
  for (; now < 1000 * kMs; now += kFrameNs) bank.step(open_at(0.9f), {.tracked = true, .now_ns = now});
  const double tracked_value = bank.values()[0];
  const std::int64_t lost_at = now - kFrameNs;  // the last tracked frame
  // Holding: the last tracked value, whatever the (untracked) signals say.
  for (; now <= lost_at + safety.hold_ns; now += kFrameNs) {
    EXPECT_EQ(bank.step(open_at(0), {.tracked = false, .now_ns = now})[0], tracked_value);
    EXPECT_FALSE(bank.fail_safe_active());
  }
  std::int64_t neutral_at = -1;
  for (; now < lost_at + 5000 * kMs && neutral_at < 0; now += kFrameNs) {
    if (bank.step(open_at(0), {.tracked = false, .now_ns = now})[0] == 1200) neutral_at = now - lost_at;
    EXPECT_TRUE(bank.fail_safe_active());
  }
  ASSERT_GE(neutral_at, 0);
  EXPECT_NEAR(static_cast<double>(neutral_at), static_cast<double>(safety.hold_ns + safety.ease_ns), kFrameNs);
}

TEST(ChannelBank, SlewLimitHoldsFrameToFrameThroughLossAndReturn) {
  ChannelSpec spec = open_channel();
  spec.max_slew_per_s = 1500;  // units per second
  ChannelBank bank({&spec, 1}, {.hold_ns = 100 * kMs, .ease_ns = 50 * kMs});
  // A jumpy signal with tracking dropping in and out and a variable frame interval.
  std::int64_t now = 0;
  double previous = bank.values()[0];
  std::int64_t previous_ns = 0;
  for (int frame = 0; frame < 2000; ++frame) {
    now += kFrameNs / 2 + (frame * 7919 % 5) * kFrameNs / 4;
    const bool tracked = (frame / 40) % 3 != 2;
    const double value = bank.step(open_at(frame % 2 ? 1.0f : 0.0f), {.tracked = tracked, .now_ns = now})[0];
    EXPECT_LE(std::abs(value - previous), 1500.0 * static_cast<double>(now - previous_ns) * 1e-9 + 1e-9) << frame;
    EXPECT_GE(value, 1000);
    EXPECT_LE(value, 2000);
    previous = value;
    previous_ns = now;
  }
}

TEST(ChannelBank, TrackingReturnEasesBackWithoutAJump) {
  const ChannelSpec spec = open_channel();
  ChannelBank bank({&spec, 1}, {.hold_ns = 100 * kMs, .ease_ns = 400 * kMs});
  std::int64_t now = 0;
  ASSERT_GT(time_to_neutral(bank, now), 0);
  double previous = bank.values()[0];
  for (int frame = 0; frame < 40; ++frame, now += kFrameNs) {
    const double value = bank.step(open_at(1), {.tracked = true, .now_ns = now})[0];
    EXPECT_LE(value - previous, 800.0 * kFrameNs / (400 * kMs) + 1e-9) << frame;
    previous = value;
  }
  EXPECT_DOUBLE_EQ(previous, 2000);
}

TEST(ChannelBank, ADriveCarriedOnFromAnotherGoesOnWhereItStoodByName) {
  // A reload: the tracked jaw at 1900 and a slew-limited lip carry on by name through the hold
  // and the ease; a channel new in the configuration starts at its neutral, one no longer in it
  // is dropped, and a value outside the new output range is brought into it.
  ChannelSpec lip = open_channel();
  lip.name = "lip";
  lip.max_slew_per_s = 1000;
  const std::vector<ChannelSpec> before{open_channel(), lip, {.name = "gone", .neutral = 0}};
  const SafetySettings safety{.hold_ns = 250 * kMs, .ease_ns = 500 * kMs};
  ChannelBank old_bank(before, safety);
  std::int64_t now = 0;
  for (; now < 2000 * kMs; now += kFrameNs) old_bank.step(open_at(0.9f), {.tracked = true, .now_ns = now});
  const ChannelBankState state = old_bank.state();
  ASSERT_EQ(state.channels.size(), 3u);
  EXPECT_NEAR(state.channels[0].value, 1900, 1e-3);
  const double lip_value = state.channels[1].value;
  EXPECT_NEAR(lip_value, 1900, 1e-3);
  EXPECT_DOUBLE_EQ(state.gain, 1);

  ChannelSpec narrower = open_channel();
  narrower.out_max = 1800;
  ChannelSpec fresh = open_channel();
  fresh.name = "new";
  const std::vector<ChannelSpec> after{fresh, lip, narrower};
  ChannelBank bank(after, safety);
  bank.carry_on(state);
  EXPECT_EQ(bank.values()[0], 1200) << "a new channel starts at its neutral";
  EXPECT_EQ(bank.values()[1], lip_value);
  EXPECT_EQ(bank.values()[2], 1800) << "clamped to the new range";
  // 100 ms without a face (the new camera opening): still within the hold, nothing moves.
  now += 100 * kMs;
  const auto values = bank.step(open_at(0), {.tracked = false, .now_ns = now});
  EXPECT_EQ(values[1], lip_value);
  EXPECT_EQ(values[2], 1800);
  EXPECT_FALSE(bank.fail_safe_active());
  // Past the hold the carried lip eases down within its slew limit, from where it was.
  double previous = values[1];
  for (int frame = 0; frame < 60; ++frame) {
    now += kFrameNs;
    const double value = bank.step(open_at(0), {.tracked = false, .now_ns = now})[1];
    EXPECT_LE(previous - value, 1000.0 * kFrameNs * 1e-9 + 1e-9) << frame;
    previous = value;
  }
  EXPECT_LT(previous, lip_value - 100);
  EXPECT_TRUE(bank.fail_safe_active());
}

TEST(ChannelBank, DisabledOutputsEaseToNeutralAndOverridesWin) {
  std::vector<ChannelSpec> specs{open_channel(), open_channel()};
  ChannelBank bank(specs, {.hold_ns = 100 * kMs, .ease_ns = 100 * kMs});
  std::int64_t now = 0;
  for (; now < 500 * kMs; now += kFrameNs) bank.step(open_at(1), {.tracked = true, .now_ns = now});
  bank.set_override(1, 1900);
  bank.set_override(0, 99999);  // clamped to the output range
  bank.step(open_at(1), {.tracked = true, .now_ns = now});
  EXPECT_EQ(bank.values()[0], 2000);
  EXPECT_EQ(bank.values()[1], 1900);
  bank.set_override(0, ChannelBank::kNoOverride);
  bank.set_override(1, ChannelBank::kNoOverride);
  // Disabled: no hold, straight into the ease.
  const std::int64_t disabled_at = now;
  for (; now < disabled_at + 100 * kMs + kFrameNs; now += kFrameNs)
    bank.step(open_at(1), {.tracked = true, .enabled = false, .now_ns = now});
  EXPECT_EQ(bank.values()[0], 1200);
  EXPECT_TRUE(bank.fail_safe_active());
}

TEST(ChannelBank, TrackingChannelReportsTheStateUneased) {
  const ChannelSpec spec{.name = "led", .signal = Signal::kTracking, .out_min = 0, .out_max = 1, .neutral = 0};
  ChannelBank bank({&spec, 1}, {});
  EXPECT_EQ(bank.step({}, {.tracked = true, .now_ns = 0})[0], 1);
  EXPECT_EQ(bank.step({}, {.tracked = false, .now_ns = kFrameNs})[0], 0);
}

TEST(ChannelBank, SmoothedChannelsFilterOnFrameTimesOnly) {
  std::vector<ChannelSpec> specs{open_channel(), open_channel()};
  specs[1].smoothed = true;
  specs[1].smoothing = {.min_cutoff_hz = 1.0, .beta = 0.0};
  ChannelBank bank(specs, {.hold_ns = 100 * kMs, .ease_ns = 0});
  // A still mouth with tracking jitter: the smoothed channel moves far less frame to frame.
  double raw_jitter = 0, smooth_jitter = 0;
  std::array<double, 2> previous{};
  std::int64_t now = 0;
  for (int frame = 0; frame < 300; ++frame, now += kFrameNs) {
    const auto values =
        bank.step(open_at(frame % 2 ? 0.52f : 0.48f), {.tracked = true, .now_ns = now, .frame_time_ns = now});
    if (frame > 100) {
      raw_jitter += std::abs(values[0] - previous[0]);
      smooth_jitter += std::abs(values[1] - previous[1]);
    }
    previous = {values[0], values[1]};
  }
  EXPECT_LT(smooth_jitter, raw_jitter / 5);
  EXPECT_NEAR(previous[1], 1500, 10);
  // An idle tick repeats the last frame: nothing to filter, nothing changes.
  const double before = bank.values()[1];
  bank.step(open_at(1), {.tracked = true, .now_ns = now + kMs, .frame_time_ns = now - kFrameNs});
  EXPECT_EQ(bank.values()[1], before);
}

TEST(ChannelBank, ASignalThatIsNotANumberKeepsTheLastTarget) {
  std::vector<ChannelSpec> specs{open_channel(), open_channel()};
  specs[1].smoothed = true;
  ChannelBank bank(specs, {.hold_ns = 100 * kMs, .ease_ns = 0});
  std::int64_t now = 0;
  for (; now < 500 * kMs; now += kFrameNs)
    bank.step(open_at(0.5f), {.tracked = true, .now_ns = now, .frame_time_ns = now});
  const std::array<double, 2> before{bank.values()[0], bank.values()[1]};
  for (const float bad : {std::nanf(""), INFINITY, -INFINITY}) {
    const auto values = bank.step(open_at(bad), {.tracked = true, .now_ns = now, .frame_time_ns = now});
    EXPECT_EQ(values[0], before[0]) << bad;
    EXPECT_EQ(values[1], before[1]) << bad;
    now += kFrameNs;
  }
  // The smoothed channel's filter never saw it: the next number is filtered as before.
  const auto values = bank.step(open_at(0.5f), {.tracked = true, .now_ns = now, .frame_time_ns = now});
  EXPECT_TRUE(std::isfinite(values[1]));
  EXPECT_NEAR(values[1], 1500, 1);
}

TEST(ChannelBank, StepAllocatesNothing) {
  std::vector<ChannelSpec> specs(kMaxChannels, open_channel());
  ChannelBank bank(specs, {});
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  for (int frame = 0; frame < 1000; ++frame)
    bank.step(open_at(static_cast<float>(frame % 10) / 10), {.tracked = frame % 100 < 70, .now_ns = frame * kFrameNs});
  const long allocations = test::allocation_count() - before;
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocations, 0);
}

TEST(DriveSource, TheFaceFirstThenTheVoiceThenTheFailSafe) {
  EXPECT_EQ(select_source(true, true), DriveSource::kVideo);
  EXPECT_EQ(select_source(true, false), DriveSource::kVideo);
  EXPECT_EQ(select_source(false, true), DriveSource::kVoice);
  EXPECT_EQ(select_source(false, false), DriveSource::kFailSafe);
  EXPECT_EQ(drive_source_name(DriveSource::kVideo), "video");
  EXPECT_EQ(drive_source_name(DriveSource::kVoice), "voice");
  EXPECT_EQ(drive_source_name(DriveSource::kFailSafe), "fail-safe");
}

TEST(HandOver, CrossFadesToTheVoiceAndBackOverTheCrossFadeTime) {
  constexpr std::int64_t kFade = 150 * kMs, kTick = 10 * kMs;
  HandOver hand_over(kFade);
  std::int64_t now = 0;
  for (; now < 100 * kMs; now += kTick)
    EXPECT_EQ(hand_over.step(DriveSource::kVideo, open_at(0.8f), open_at(0.2f), now)[Signal::kOpen], 0.8f);
  // The face is lost: from the last video value to the voice in 150 ms, never a jump.
  float last = 0.8f;
  const std::int64_t lost = now;
  for (; now <= lost + kFade; now += kTick) {
    const float open = hand_over.step(DriveSource::kVoice, open_at(0.0f), open_at(0.2f), now)[Signal::kOpen];
    EXPECT_LE(open, last);
    EXPECT_NEAR(open, last, 0.6f * kTick / kFade + 1e-5f);
    last = open;
  }
  EXPECT_FLOAT_EQ(last, 0.2f);
  EXPECT_DOUBLE_EQ(hand_over.voice_weight(), 1.0);
  // Under the fail-safe the mix stays where it was (the channels hold and ease).
  EXPECT_FLOAT_EQ(hand_over.step(DriveSource::kFailSafe, open_at(0.5f), open_at(0.9f), now)[Signal::kOpen], 0.2f);
  now += kTick;
  // The face returns: back to the video in 150 ms.
  const std::int64_t back = now;
  for (; now < back + kFade - kTick; now += kTick)
    EXPECT_LT(hand_over.step(DriveSource::kVideo, open_at(0.6f), open_at(0.9f), now)[Signal::kOpen], 0.6f);
  for (; now <= back + kFade; now += kTick) hand_over.step(DriveSource::kVideo, open_at(0.6f), open_at(0.9f), now);
  EXPECT_FLOAT_EQ(hand_over.step(DriveSource::kVideo, open_at(0.6f), open_at(0.9f), now)[Signal::kOpen], 0.6f);
  EXPECT_DOUBLE_EQ(hand_over.voice_weight(), 0.0);
  // Whole, a source passes as it is: the last face's NaN does not leak into the voice as 0 * NaN.
  hand_over.step(DriveSource::kVideo, open_at(NAN), open_at(0.9f), now);
  for (const std::int64_t lost_again = now; now <= lost_again + 2 * kFade; now += kTick)
    hand_over.step(DriveSource::kVoice, open_at(0.0f), open_at(0.9f), now);
  EXPECT_FLOAT_EQ(hand_over.step(DriveSource::kVoice, open_at(0.0f), open_at(0.9f), now)[Signal::kOpen], 0.9f);
}

TEST(ChannelBank, TheVoiceDrivesLikeAFaceAndItsLossIsTheFailSafe) {
  const ChannelSpec spec = open_channel();
  const SafetySettings safety{.hold_ns = 250 * kMs, .ease_ns = 500 * kMs};
  ChannelBank bank({&spec, 1}, safety);
  std::int64_t now = 0;
  for (; now < 1000 * kMs; now += kFrameNs) bank.step(open_at(0.9f), {.tracked = true, .now_ns = now});
  // The face is lost, the voice drives: no hold, no ease, the voice's values.
  for (; now < 2000 * kMs; now += kFrameNs) {
    bank.step(open_at(0.5f), {.tracked = false, .voice = true, .now_ns = now});
    EXPECT_FALSE(bank.fail_safe_active());
  }
  EXPECT_DOUBLE_EQ(bank.values()[0], 1500);
  // The sound goes too: the fail-safe as ever, hold then ease to neutral within hold + ease.
  const std::int64_t lost_at = now - kFrameNs;
  std::int64_t neutral_at = -1;
  for (; now < lost_at + 5000 * kMs && neutral_at < 0; now += kFrameNs)
    if (bank.step(open_at(0), {.tracked = false, .now_ns = now})[0] == 1200) neutral_at = now - lost_at;
  ASSERT_GE(neutral_at, 0);
  EXPECT_NEAR(static_cast<double>(neutral_at), static_cast<double>(safety.hold_ns + safety.ease_ns), kFrameNs);
}

TEST(HandOver, StepAllocatesNothing) {
  HandOver hand_over(150 * kMs);
  test::count_allocations_on_this_thread(true);
  const long before = test::allocation_count();
  for (int frame = 0; frame < 1000; ++frame)
    hand_over.step(static_cast<DriveSource>(frame / 100 % 3), open_at(0.5f), open_at(0.2f), frame * kFrameNs);
  const long allocations = test::allocation_count() - before;
  test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocations, 0);
}

TEST(Calibration, ScalesEachMeasureIntoItsRange) {
  PerformerProfile profile;
  profile.open = {0.1, 0.5};
  profile.width = {1.0, 0.8};  // inverted ranges are allowed
  MouthMeasures m;
  m.open = 0.3;
  m.width_fit = 0.85;
  m.protrusion_3d = -1;
  const std::array<float, 2> visemes{0.25f, 0.5f};
  const DriveSignals s = drive_signals(m, visemes, profile);
  EXPECT_FLOAT_EQ(s[Signal::kOpen], 0.5f);
  EXPECT_FLOAT_EQ(s[Signal::kWidth], 0.75f);
  EXPECT_FLOAT_EQ(s[Signal::kProtrusion], 0.0f);
  EXPECT_FLOAT_EQ(s[Signal::kTracking], 1.0f);
  EXPECT_FLOAT_EQ(s[viseme_signal(1)], 0.5f);
}

}  // namespace
}  // namespace lipdrive
