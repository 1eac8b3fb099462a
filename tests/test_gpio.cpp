// The GPIO output's logic against a fake chip (the GpioLines seam), the debouncer on exact
// timings, and the real libgpiod driver's errors (this machine has no GPIO chip).
#include "drivers/gpio_lines.hpp"
#include "firmware_app/outputs/debouncer.hpp"
#include "firmware_app/outputs/gpio_output.hpp"

#include "tests/captured_log.hpp"

#include <gpiod.hpp>
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace lipdrive {
namespace {

using testing::CapturedLog;

constexpr std::int64_t kMs = 1'000'000;
/// A connected camera on an enabled drive, and with a tracked face.
constexpr std::uint16_t kCamera = kStatusCameraConnected | kStatusOutputsEnabled;
constexpr std::uint16_t kTrackingOk = kStatusTracking | kCamera;

/// What the fake chip's lines hold; the test keeps it while the output owns the fake.
struct FakeChip {
  bool present = true;                  // false: every call fails as after an unplug
  std::map<std::string, bool> outputs;  // level of each output line
  std::map<std::string, bool> inputs;   // level of each input line, set by the test
  int writes = 0;
  int reopens = 0;
};

class FakeGpioLines final : public GpioLines {
 public:
  explicit FakeGpioLines(FakeChip& chip) : chip_(chip) {}

  void set_output(const std::string& line, bool active) override {
    check(line, chip_.outputs);
    chip_.outputs[line] = active;
    ++chip_.writes;
  }
  bool read_input(const std::string& line) override {
    check(line, chip_.inputs);
    return chip_.inputs[line];
  }
  void reopen() override {
    ++chip_.reopens;
    if (!chip_.present) throw GpioError("gpio chip fake: no such chip");
    for (auto& [line, level] : chip_.outputs) level = false;  // outputs restart inactive
  }
  std::string describe() const override { return "gpio fake"; }

 private:
  void check(const std::string& line, const std::map<std::string, bool>& lines) const {
    if (!chip_.present) throw GpioError("gpio chip fake: line " + line + ": No such device");
    if (!lines.contains(line)) throw GpioError("gpio chip fake: line " + line + ": not requested");
  }

  FakeChip& chip_;
};

GpioOptions all_lines() {
  GpioOptions options;
  options.enabled = true;
  options.status_line = "17";
  options.fault_line = "27";
  options.calibrate_button = "GPIO22";
  options.record_button = "GPIO23";
  options.debounce_ms = 30;
  return options;
}

/// Every line, and the enable switch (hold-to-run) on GPIO24.
GpioOptions all_lines_and_switch() {
  GpioOptions options = all_lines();
  options.enable_switch = "GPIO24";
  return options;
}

DriveFrame frame_at(std::int64_t time_ns, std::uint16_t status = kTrackingOk) {
  DriveFrame frame;
  frame.time_ns = time_ns;
  frame.status = status;
  return frame;
}

class GpioOutputTest : public ::testing::Test {
 protected:
  GpioOutputTest() {
    chip.outputs = {{"17", false}, {"27", false}};
    chip.inputs = {{"GPIO22", false}, {"GPIO23", false}, {"GPIO24", false}};
  }

  /// Publishes every 20 ms (the slowest the output thread ticks) from `from_ns` until
  /// before `to_ns`, with `button` held at `level`; returns the next tick's time.
  std::int64_t hold(const std::string& button, bool level, std::int64_t from_ns, std::int64_t to_ns) {
    chip.inputs[button] = level;
    std::int64_t now = from_ns;
    for (; now < to_ns; now += 20 * kMs) output.publish(frame_at(now, status));
    return now;
  }

  /// A clean press of `button` at `start_ns`: held 100 ms, released 100 ms.
  std::int64_t press(const std::string& button, std::int64_t start_ns) {
    const std::int64_t released = hold(button, true, start_ns, start_ns + 100 * kMs);
    return hold(button, false, released, released + 100 * kMs);
  }

  bool enabled() const { return control.enable_switch_closed.load(); }

  std::uint16_t status = kTrackingOk;  // the status word of the frames hold() publishes
  FakeChip chip;
  DriveControl control;
  GpioOutput output{all_lines_and_switch(), std::make_unique<FakeGpioLines>(chip), control};
};

TEST(Debouncer, ReportsAPressOnceTheLevelHeldForTheDebounceTime) {
  Debouncer debouncer(30 * kMs);
  EXPECT_FALSE(debouncer.press(false, 0));
  EXPECT_FALSE(debouncer.press(true, 10 * kMs));
  EXPECT_FALSE(debouncer.press(true, 39 * kMs)) << "held 29 ms of 30";
  EXPECT_TRUE(debouncer.press(true, 40 * kMs));
  EXPECT_FALSE(debouncer.press(true, 100 * kMs)) << "a held button is one press";
  EXPECT_FALSE(debouncer.press(false, 110 * kMs));
  EXPECT_FALSE(debouncer.press(false, 150 * kMs)) << "the release is accepted, not a press";
  EXPECT_FALSE(debouncer.press(true, 160 * kMs));
  EXPECT_TRUE(debouncer.press(true, 190 * kMs)) << "the second press";
}

TEST(Debouncer, RejectsBouncesShorterThanTheDebounceTime) {
  Debouncer debouncer(30 * kMs);
  debouncer.press(false, 0);
  // Contact bounce: 25 ms closed, 5 ms open, 25 ms closed, ... never 30 ms in one state.
  for (std::int64_t t = 5 * kMs; t < 500 * kMs; t += 5 * kMs)
    EXPECT_FALSE(debouncer.press((t / kMs) % 30 < 25, t)) << "at " << t / kMs << " ms";
}

TEST(Debouncer, ABouncingReleaseDoesNotMakeASecondPress) {
  Debouncer debouncer(30 * kMs);
  debouncer.press(false, 0);
  debouncer.press(true, 10 * kMs);
  ASSERT_TRUE(debouncer.press(true, 40 * kMs));
  // Released with a 10 ms bounce back to closed: the level never stays open for 30 ms
  // before it closes again, so the accepted state stays pressed.
  EXPECT_FALSE(debouncer.press(false, 50 * kMs));
  EXPECT_FALSE(debouncer.press(true, 60 * kMs));
  EXPECT_FALSE(debouncer.press(true, 100 * kMs));
}

TEST(Debouncer, AButtonHeldAtTheFirstSampleIsNoPress) {
  Debouncer debouncer(30 * kMs);
  EXPECT_FALSE(debouncer.press(true, 0));
  EXPECT_FALSE(debouncer.press(true, 100 * kMs));
  debouncer.reset();
  EXPECT_FALSE(debouncer.press(true, 200 * kMs)) << "after reset() the level starts over";
}

TEST_F(GpioOutputTest, OnePressMakesExactlyOneCalibrateRequest) {
  std::int64_t now = hold("GPIO22", false, 0, 100 * kMs);
  now = press("GPIO22", now);
  EXPECT_EQ(control.calibrate_requests.load(), 1u);
  // Held for a long time: still one request.
  now = hold("GPIO22", true, now, now + 2000 * kMs);
  hold("GPIO22", false, now, now + 100 * kMs);
  EXPECT_EQ(control.calibrate_requests.load(), 2u);
  EXPECT_EQ(control.recording_request.load(), -1) << "the record button was not touched";
}

TEST_F(GpioOutputTest, BouncesShorterThanTheDebounceTimeMakeNoRequest) {
  std::int64_t now = hold("GPIO22", false, 0, 100 * kMs);
  // Closed for one 20 ms tick at a time, 40 ms apart.
  for (int bounce = 0; bounce < 10; ++bounce) {
    now = hold("GPIO22", true, now, now + 20 * kMs);
    now = hold("GPIO22", false, now, now + 40 * kMs);
  }
  EXPECT_EQ(control.calibrate_requests.load(), 0u);
}

TEST_F(GpioOutputTest, RecordPressStartsATakeOrStopsTheOneRecording) {
  std::int64_t now = hold("GPIO23", false, 0, 100 * kMs);
  now = press("GPIO23", now);
  EXPECT_EQ(control.recording_request.load(), 1) << "nothing recording: start";

  control.recording_request.store(-1);  // the daemon acted on it
  status = kTrackingOk | kStatusRecording | kStatusCalibrated;
  now = press("GPIO23", now);
  EXPECT_EQ(control.recording_request.load(), 0) << "recording: stop";

  control.recording_request.store(-1);
  status = kTrackingOk | kStatusCalibrated;
  press("GPIO23", now);
  EXPECT_EQ(control.recording_request.load(), 1);
  EXPECT_EQ(control.calibrate_requests.load(), 0u);
}

TEST_F(GpioOutputTest, StatusAndFaultLinesFollowTheDriveFrame) {
  output.publish(frame_at(0, kTrackingOk));
  EXPECT_TRUE(chip.outputs["17"]);
  EXPECT_FALSE(chip.outputs["27"]);

  output.publish(frame_at(20 * kMs, kCamera));  // face lost, fail-safe not yet
  EXPECT_FALSE(chip.outputs["17"]);
  EXPECT_FALSE(chip.outputs["27"]);

  output.publish(frame_at(40 * kMs, kCamera | kStatusFailSafe));
  EXPECT_FALSE(chip.outputs["17"]);
  EXPECT_TRUE(chip.outputs["27"]);

  output.publish(frame_at(60 * kMs, kTrackingOk | kStatusFailSafe));  // easing back
  EXPECT_FALSE(chip.outputs["17"]) << "tracking but still in fail-safe is not OK";
  EXPECT_TRUE(chip.outputs["27"]);

  output.publish(frame_at(80 * kMs, kStatusTracking | kStatusOutputsEnabled));  // the camera just went away
  EXPECT_TRUE(chip.outputs["27"]);

  output.publish(frame_at(100 * kMs, kTrackingOk));
  EXPECT_TRUE(chip.outputs["17"]);
  EXPECT_FALSE(chip.outputs["27"]);

  // Outputs disabled (the command or the enable switch): the drive rests, on purpose.
  output.publish(frame_at(120 * kMs, kStatusTracking | kStatusCameraConnected | kStatusFailSafe));
  EXPECT_FALSE(chip.outputs["17"]);
  EXPECT_FALSE(chip.outputs["27"]) << "a drive disabled on purpose is no fault";
  output.publish(frame_at(140 * kMs, kStatusTracking | kStatusFailSafe));  // and the camera went away
  EXPECT_TRUE(chip.outputs["27"]);
}

TEST_F(GpioOutputTest, WritesOutputLinesOnlyWhenTheyChange) {
  output.publish(frame_at(0));
  EXPECT_EQ(chip.writes, 2) << "the first publish writes both lines";
  for (int i = 1; i <= 50; ++i) output.publish(frame_at(i * 20 * kMs));
  EXPECT_EQ(chip.writes, 2);
  output.publish(frame_at(1100 * kMs, kCamera));
  EXPECT_EQ(chip.writes, 3) << "only the status line changed";
}

TEST_F(GpioOutputTest, ALostChipIsLoggedOnceRetriedWithBackOffAndRecovers) {
  CapturedLog log;
  output.publish(frame_at(0));
  ASSERT_TRUE(output.healthy());

  chip.present = false;
  chip.inputs["GPIO22"] = true;  // held through the outage: must not count as a press
  std::int64_t now = 20 * kMs;
  EXPECT_NO_THROW(output.publish(frame_at(now, kCamera)));
  EXPECT_FALSE(output.healthy());
  EXPECT_EQ(chip.reopens, 0) << "the first retry waits for the back-off";

  // Ticks up to 3 s: retries at 120, 320, 720 and 1520 ms (the back-off doubles from 100 ms),
  // the next one is due at 3120 ms.
  for (now += 20 * kMs; now < 3020 * kMs; now += 20 * kMs) EXPECT_NO_THROW(output.publish(frame_at(now, kCamera)));
  EXPECT_EQ(chip.reopens, 4) << "back-off doubles: retries do not come every tick";
  EXPECT_FALSE(output.healthy());
  EXPECT_EQ(log.count(spdlog::level::err), 1) << "the loss is logged once, not per retry";

  chip.present = true;
  for (const std::int64_t end = now + 5000 * kMs; now < end && !output.healthy(); now += 20 * kMs)
    output.publish(frame_at(now, kTrackingOk));
  ASSERT_TRUE(output.healthy());
  EXPECT_EQ(chip.reopens, 5);
  EXPECT_EQ(log.count(spdlog::level::info), 1) << "the recovery is logged";
  EXPECT_EQ(now, 3140 * kMs) << "recovered at the retry due at 3120 ms";
  EXPECT_TRUE(chip.outputs["17"]) << "the status line is written again after the reopen";

  hold("GPIO22", true, now, now + 200 * kMs);
  EXPECT_EQ(control.calibrate_requests.load(), 0u) << "a button held across the outage is no press";
}

TEST(GpioOutput, UnusedLinesAreNeitherWrittenNorRead) {
  FakeChip chip;  // no lines requested at all: any access would fail
  DriveControl control;
  GpioOptions options;
  options.enabled = true;
  GpioOutput output(options, std::make_unique<FakeGpioLines>(chip), control);
  output.publish(frame_at(0));
  EXPECT_TRUE(output.healthy());
  EXPECT_EQ(output.describe(), "gpio fake (no lines)");
}

TEST(GpioOutput, DescribeNamesTheChipAndTheLines) {
  FakeChip chip;
  DriveControl control;
  GpioOutput output(all_lines(), std::make_unique<FakeGpioLines>(chip), control);
  EXPECT_EQ(output.describe(), "gpio fake (status 17, fault 27, calibrate GPIO22, record GPIO23)");
}

TEST_F(GpioOutputTest, EnableSwitchTheDriveWaitsForTheFirstReadingOfTheSwitch) {
  EXPECT_FALSE(enabled()) << "open from construction until the switch is read";
  EXPECT_EQ(output.describe(), "gpio fake (status 17, fault 27, calibrate GPIO22, record GPIO23, enable GPIO24)");
  hold("GPIO24", true, 0, 1);
  EXPECT_TRUE(enabled()) << "closed at the first sample: no debounce wait at start";
}

TEST_F(GpioOutputTest, EnableSwitchOpenAtStartKeepsTheDriveDisabledUntilClosed) {
  std::int64_t now = hold("GPIO24", false, 0, 500 * kMs);
  EXPECT_FALSE(enabled());
  now = hold("GPIO24", true, now, now + 20 * kMs);
  EXPECT_FALSE(enabled()) << "closed for less than the debounce time";
  hold("GPIO24", true, now, now + 40 * kMs);
  EXPECT_TRUE(enabled());
}

TEST_F(GpioOutputTest, EnableSwitchReleasingDisablesOnceTheReleaseHeldForTheDebounceTime) {
  CapturedLog log;
  std::int64_t now = hold("GPIO24", true, 0, 100 * kMs);
  ASSERT_TRUE(enabled());
  // Contact bounce: open for one 20 ms tick at a time, 40 ms apart.
  for (int bounce = 0; bounce < 10; ++bounce) {
    now = hold("GPIO24", false, now, now + 20 * kMs);
    now = hold("GPIO24", true, now, now + 40 * kMs);
    EXPECT_TRUE(enabled()) << "bounce " << bounce;
  }
  now = hold("GPIO24", false, now, now + 60 * kMs);
  EXPECT_FALSE(enabled()) << "released for 60 ms, debounce 30 ms";
  EXPECT_EQ(log.count(spdlog::level::warn), 1) << "the release is logged";
  hold("GPIO24", true, now, now + 60 * kMs);
  EXPECT_TRUE(enabled());
  EXPECT_EQ(control.calibrate_requests.load(), 0u) << "the switch is not a button";
  EXPECT_EQ(control.recording_request.load(), -1);
}

TEST_F(GpioOutputTest, EnableSwitchALostChipOpensTheSwitchUntilItIsReadClosedAgain) {
  std::int64_t now = hold("GPIO24", true, 0, 100 * kMs);
  ASSERT_TRUE(enabled());
  chip.present = false;
  now = hold("GPIO24", true, now, now + 20 * kMs);
  EXPECT_FALSE(output.healthy());
  EXPECT_FALSE(enabled()) << "a switch that cannot be read does not let the figure move";
  // The chip back after 1 s (the retry due 1.5 s after the loss reopens it), the switch
  // released meanwhile.
  now = hold("GPIO24", true, now, now + 1000 * kMs);
  chip.present = true;
  now = hold("GPIO24", false, now, now + 1000 * kMs);
  ASSERT_TRUE(output.healthy());
  EXPECT_FALSE(enabled()) << "read open after the reopen";
  hold("GPIO24", true, now, now + 60 * kMs);
  EXPECT_TRUE(enabled());
}

TEST(GpioOutput, WithoutAnEnableSwitchTheDriveStaysEnabledEvenWhenTheChipIsLost) {
  FakeChip chip;
  chip.present = false;
  DriveControl control;
  GpioOutput output(all_lines(), std::make_unique<FakeGpioLines>(chip), control);
  output.publish(frame_at(0));
  EXPECT_FALSE(output.healthy());
  EXPECT_TRUE(control.enable_switch_closed.load());
}

TEST(GpioOutput, InputsRestReleasedThroughTheChipsResistorUnlessConfiguredOtherwise) {
  // An input nothing drives (an open contact, a cut cable) must read released: by default
  // active-low inputs get the chip's pull-up, active-high ones its pull-down, where the kernel
  // can set it; a bias named in the configuration is asked for exactly.
  GpioOptions options = all_lines_and_switch();
  using Request = gpiod::line_request;
  for (const GpioBias bias : {GpioBias::kAuto, GpioBias::kDisable}) {
    options.input_bias = bias;
    for (const bool active_low : {true, false}) {
      options.buttons_active_low = active_low;
      const std::vector<GpioLineSpec> specs = gpio_line_specs(options);
      ASSERT_EQ(specs.size(), 5u);
      for (const GpioLineSpec& spec : specs) {
        SCOPED_TRACE(spec.line);
        if (spec.direction == GpioDirection::kOutput) {
          EXPECT_EQ(gpiod_request_flags(spec), std::bitset<32>()) << "outputs drive their line";
          continue;
        }
        EXPECT_EQ(spec.bias, bias);
        const std::bitset<32> pull = bias == GpioBias::kDisable ? Request::FLAG_BIAS_DISABLE
                                     : active_low               ? Request::FLAG_BIAS_PULL_UP
                                                                : Request::FLAG_BIAS_PULL_DOWN;
        EXPECT_EQ(gpiod_request_flags(spec), active_low ? Request::FLAG_ACTIVE_LOW | pull : pull);
      }
    }
  }
}

TEST(GpiodChipLines, TheRequestAsksForTheBiasOfInputsBesideActiveLow) {
  using Request = gpiod::line_request;
  const auto flags = [](GpioDirection direction, bool active_low, GpioBias bias) {
    return gpiod_request_flags({"17", direction, active_low, bias});
  };
  EXPECT_EQ(flags(GpioDirection::kInput, true, GpioBias::kPullUp),
            Request::FLAG_ACTIVE_LOW | Request::FLAG_BIAS_PULL_UP);
  EXPECT_EQ(flags(GpioDirection::kInput, true, GpioBias::kPullDown),
            Request::FLAG_ACTIVE_LOW | Request::FLAG_BIAS_PULL_DOWN);
  EXPECT_EQ(flags(GpioDirection::kInput, false, GpioBias::kPullDown), Request::FLAG_BIAS_PULL_DOWN);
  EXPECT_EQ(flags(GpioDirection::kInput, false, GpioBias::kDisable), Request::FLAG_BIAS_DISABLE);
  EXPECT_EQ(flags(GpioDirection::kInput, true, GpioBias::kAsIs), Request::FLAG_ACTIVE_LOW);
  EXPECT_EQ(flags(GpioDirection::kOutput, false, GpioBias::kPullUp), std::bitset<32>()) << "outputs drive their line";
}

TEST(GpiodChipLines, AMissingChipIsAnErrorNamingIt) {
  GpioOptions options = all_lines();
  for (const std::string chip : {"gpiochip7", "/dev/gpiochip7"}) {
    options.chip = chip;
    try {
      open_gpio_chip(options);
      ADD_FAILURE() << chip << " opened";
    } catch (const GpioError& error) {
      EXPECT_EQ(std::string(error.what()), "gpio chip " + chip + ": no such chip");
    }
  }
}

TEST(GpiodChipLines, CheckingNamesAMissingChipOrADeviceThatIsNone) {
  const std::vector<GpioLineSpec> lines = {{"17", GpioDirection::kOutput, false}};
  try {
    check_gpiod_chip("gpiochip7", lines);
    ADD_FAILURE() << "gpiochip7 checked";
  } catch (const GpioError& error) {
    EXPECT_EQ(std::string(error.what()), "gpio chip gpiochip7: no such chip");
  }
  try {
    check_gpiod_chip("/dev/null", lines);
    ADD_FAILURE() << "/dev/null checked as a GPIO chip";
  } catch (const GpioError& error) {
    EXPECT_EQ(std::string(error.what()), "gpio chip /dev/null: not a GPIO chip");
  }
}

TEST(GpiodChipLines, ADeviceThatIsNoGpioChipIsAnError) {
  try {
    open_gpiod_chip("/dev/null", {{"17", GpioDirection::kOutput, false}});
    ADD_FAILURE() << "/dev/null opened as a GPIO chip";
  } catch (const GpioError& error) {
    EXPECT_EQ(std::string(error.what()), "gpio chip /dev/null: not a GPIO chip");
  }
}

}  // namespace
}  // namespace lipdrive
