// Performer calibration (docs/method.md 4 "Scaled"): neutral + range of motion -> [0, 1].
#include "core/calibration.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace lipdrive {
namespace {

std::vector<CalibrationSample> still_face(int frames, CalibrationSample rest) {
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < frames; ++i)
    samples.push_back({rest.open + 0.002 * std::sin(i), rest.width + 0.003 * std::cos(i), rest.protrusion});
  return samples;
}

/// open / wide / round / closed, with two mistracked frames far outside.
std::vector<CalibrationSample> range_of_motion() {
  std::vector<CalibrationSample> samples;
  for (int i = 0; i < 200; ++i) {
    const double phase = i / 200.0;
    samples.push_back({0.4 * std::max(0.0, std::sin(6.283 * phase)), 0.85 + 0.2 * std::sin(12.566 * phase),
                       0.03 * std::max(0.0, -std::sin(6.283 * phase))});
  }
  samples.push_back({5, 5, 5});
  samples.push_back({-5, -5, -5});
  return samples;
}

TEST(Calibration, RangesRunFromRestToTheRobustExtremes) {
  const PerformerProfile profile = calibrate(still_face(30, {0.02, 0.85, 0.0}), range_of_motion());
  EXPECT_TRUE(profile.calibrated);
  EXPECT_NEAR(profile.rest.open, 0.02, 0.003);
  EXPECT_NEAR(profile.open.min, 0.02, 0.003);
  EXPECT_NEAR(profile.open.max, 0.4, 0.01) << "the outlier frame does not set the end";
  EXPECT_NEAR(profile.width.min, 0.65, 0.01);
  EXPECT_NEAR(profile.width.max, 1.05, 0.01);
  EXPECT_NEAR(profile.protrusion.max, 0.03, 0.002);
  // At rest everything but width reads 0; wide open reads 1.
  MouthMeasures rest;
  rest.open = 0.02;
  rest.width_fit = 0.85;
  const DriveSignals at_rest = drive_signals(rest, {}, profile);
  EXPECT_NEAR(at_rest[Signal::kOpen], 0, 0.01);
  EXPECT_NEAR(at_rest[Signal::kWidth], 0.5, 0.03);
  MouthMeasures open = rest;
  open.open = 0.45;
  EXPECT_FLOAT_EQ(drive_signals(open, {}, profile)[Signal::kOpen], 1.0f);
}

TEST(Calibration, RefusesCapturesThatCannotCalibrate) {
  EXPECT_THROW(calibrate(still_face(3, {}), range_of_motion()), CalibrationError);
  try {
    calibrate(still_face(30, {0.02, 0.85, 0}), still_face(100, {0.02, 0.85, 0}));
    FAIL() << "a motionless range of motion must not calibrate";
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("mouth opening"), std::string::npos) << e.what();
  }
}

TEST(Calibration, RecentringFollowsAHelmetSlipAndKeepsTheSpans) {
  const PerformerProfile profile = calibrate(still_face(30, {0.02, 0.85, 0.0}), range_of_motion());
  // The helmet slipped: at rest the mouth now reads a little open and wider.
  const PerformerProfile moved = recentre(profile, still_face(30, {0.05, 0.9, 0.01}));
  EXPECT_NEAR(moved.open.min, 0.05, 0.003);
  EXPECT_NEAR(moved.open.max - moved.open.min, profile.open.max - profile.open.min, 1e-9);
  EXPECT_NEAR(moved.width.min - profile.width.min, 0.05, 0.005);
  EXPECT_NEAR(moved.protrusion.min, 0.01, 1e-9);
  MouthMeasures rest;
  rest.open = 0.05;
  rest.width_fit = 0.9;
  rest.protrusion_3d = 0.01;
  EXPECT_NEAR(drive_signals(rest, {}, moved)[Signal::kOpen], 0, 0.01);
}

TEST(Calibration, CaptureKeepsAtMostItsCapacity) {
  CalibrationCapture capture;
  MouthMeasures m;
  m.open = 0.3;
  for (int i = 0; i < CalibrationCapture::kCapacity + 10; ++i) capture.add(m);
  EXPECT_EQ(capture.size(), CalibrationCapture::kCapacity);
  EXPECT_EQ(capture.samples()[0].open, 0.3);
  capture.clear();
  EXPECT_EQ(capture.size(), 0);
}

}  // namespace
}  // namespace lipdrive
