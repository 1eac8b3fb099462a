// Performer calibration (docs/method.md 4 "Scaled"): neutral + range of motion -> [0, 1]; the
// profile file with the performer's identity (docs/method.md 3), and old profiles.
#include "command_run.hpp"
#include "core/calibration.hpp"
#include "core/model_format.hpp"
#include "firmware_app/cli/command_error.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "fixture_paths.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
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
  // A measure that is not a number in every frame (a model that cannot measure it) is no range.
  std::vector<CalibrationSample> no_width = range_of_motion();
  for (CalibrationSample& s : no_width) s.width = std::nan("");
  EXPECT_THROW(calibrate(still_face(30, {0.02, 0.85, 0}), no_width), CalibrationError);
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
  m.width_fit = std::nan("");
  capture.add(m);
  EXPECT_EQ(capture.size(), 0) << "a frame with a measure that is not a number is left out";
  EXPECT_EQ(capture.size(), 0);
}

TEST(Calibration, IdentityIsTheFittersVectorZeroPastItsComponents) {
  PerformerIdentity identity;
  identity.components = 3;
  identity.alpha[0] = 0.5f, identity.alpha[1] = -1.25f, identity.alpha[2] = 2.0f, identity.alpha[3] = 9.0f;
  const Eigen::VectorXf five = identity.vector(5);
  ASSERT_EQ(five.size(), 5);
  EXPECT_EQ(five[1], -1.25f);
  EXPECT_EQ(five[3], 0.0f) << "past the fitted components";
  EXPECT_EQ(identity.vector(2).size(), 2);
}

class ProfileFile : public ::testing::Test {
 protected:
  void SetUp() override { std::filesystem::create_directories(dir_); }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path write(const std::string& text) {
    const auto file = dir_ / "p.toml";
    std::ofstream(file) << text;
    return file;
  }
  std::string load_error(const std::string& text) {
    try {
      load_profile(write(text), "old");
    } catch (const CommandError& e) {
      return e.what();
    }
    return "";
  }
  std::filesystem::path dir_ = std::filesystem::temp_directory_path() / fmt::format("lipdrive_profile_{}", ::getpid());
};

constexpr const char* kVersionOneProfile =
    "version = 1\nperformer = \"old\"\n[rest]\nopen = 0.03\nwidth = 1.3\nprotrusion = 0.0\n"
    "[open]\nmin = 0.03\nmax = 0.35\n[width]\nmin = 1.0\nmax = 1.8\n[protrusion]\nmin = -0.02\nmax = 0.18\n";

TEST_F(ProfileFile, IdentityRoundTripsAndAVersionOneProfileStillLoads) {
  PerformerProfile profile;
  PerformerIdentity identity;
  identity.model_fingerprint = 0xF00DCAFEu;
  identity.components = 20;
  for (int i = 0; i < 20; ++i) identity.alpha[static_cast<std::size_t>(i)] = 0.1f * static_cast<float>(i) - 0.77f;
  identity.expressions = 53;
  for (int e = 0; e < 53; ++e) identity.rest[static_cast<std::size_t>(e)] = 0.013f * static_cast<float>(e);
  profile.identity = identity;
  save_profile(dir_ / "a.toml", "a", profile);
  const PerformerProfile loaded = load_profile(dir_ / "a.toml", "a");
  ASSERT_TRUE(loaded.identity.has_value());
  EXPECT_EQ(loaded.identity->model_fingerprint, 0xF00DCAFEu);
  EXPECT_EQ(loaded.identity->components, 20);
  EXPECT_EQ(loaded.identity->alpha, identity.alpha) << "every float exactly";
  EXPECT_EQ(loaded.identity->expressions, 53);
  EXPECT_EQ(loaded.identity->rest, identity.rest) << "the rest point, every float exactly";
  EXPECT_EQ(loaded.identity->rest_weights()[52], identity.rest[52]);
  EXPECT_EQ(loaded.identity->rest_weights()[53], 0.0);

  const PerformerProfile old = load_profile(write(kVersionOneProfile), "old");
  EXPECT_FALSE(old.identity.has_value()) << "version 1 has no identity: the mean face";
  EXPECT_DOUBLE_EQ(old.open.max, 0.35);
}

TEST_F(ProfileFile, AMalformedIdentityIsAnErrorNamingTheKey) {
  const std::string v2 = std::string(kVersionOneProfile).replace(0, 11, "version = 2");
  using ::testing::HasSubstr;
  EXPECT_THAT(load_error(v2 + "[identity]\nalpha = [0.5]\n"), HasSubstr("key identity.model_fingerprint"));
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = -1\nalpha = [0.5]\n"),
              HasSubstr("key identity.model_fingerprint"));
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = []\n"), HasSubstr("key identity.alpha"));
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = [0.5, \"x\"]\n"),
              HasSubstr("key identity.alpha[1]"));
  std::string too_many = "0.5";
  for (int i = 1; i <= kMaxFitComponents; ++i) too_many += ", 0.5";
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = [" + too_many + "]\n"),
              HasSubstr("key identity.alpha: missing, or not an array of 1 to 40 numbers"));
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = [0.5]\nrest_expression = [0.5, 1.5]\n"),
              HasSubstr("key identity.rest_expression[1]: not a number in [0, 1]"));
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = [0.5]\nrest_expression = 0.5\n"),
              HasSubstr("key identity.rest_expression"));
  EXPECT_THAT(load_error(std::string(kVersionOneProfile) + "[identity]\nmodel_fingerprint = 7\nalpha = [0.5]\n"),
              HasSubstr("key identity: needs version 2"));
  EXPECT_THAT(load_error(std::string(kVersionOneProfile).replace(0, 11, "version = 3")), HasSubstr("key version"));
  // Numbers that are not integers are refused, not converted (fuzz_profile: converting
  // 8.3677e92 to an integer was undefined behaviour).
  EXPECT_THAT(load_error(std::string(kVersionOneProfile).replace(0, 11, "version = 83677e88")),
              HasSubstr("key version"));
  EXPECT_THAT(load_error(std::string(kVersionOneProfile).replace(0, 11, "version = 1.5")), HasSubstr("key version"));
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = 1e300\nalpha = [0.5]\n"),
              HasSubstr("key identity.model_fingerprint"));
}

/// kVersionOneProfile with its first `from` replaced by `to`.
std::string with(const std::string& from, const std::string& to) {
  const std::string v1 = kVersionOneProfile;
  return std::string(v1).replace(v1.find(from), from.size(), to);
}

TEST_F(ProfileFile, ANumberThatIsNotFiniteOrARangeThatRunsBackwardsIsAnErrorNamingTheKey) {
  using ::testing::HasSubstr;
  const std::string at = (dir_ / "p.toml").string() + ": key ";
  EXPECT_EQ(load_error(with("min = 0.03", "min = nan")), at + "open.min: must be a finite number, got nan");
  EXPECT_EQ(load_error(with("max = 1.8", "max = inf")), at + "width.max: must be a finite number, got inf");
  EXPECT_EQ(load_error(with("protrusion = 0.0", "protrusion = -inf")),
            at + "rest.protrusion: must be a finite number, got -inf");
  EXPECT_EQ(load_error(with("max = 0.35", "max = 0.01")), at + "open.max: must be above min 0.03, got 0.01");
  EXPECT_EQ(load_error(with("max = 0.35", "max = 0.03")), at + "open.max: must be above min 0.03, got 0.03");
}

TEST_F(ProfileFile, AValueNoCalibrationMeasuresOrAnotherPerformersFileIsAnErrorNamingTheKey) {
  using ::testing::HasSubstr;
  const std::string at = (dir_ / "p.toml").string() + ": key ";
  EXPECT_EQ(load_error(with("open = 0.03", "open = 1e300")),
            at + "rest.open: must be within ±10 (a mouth measure over the eyes-to-nose distance), got 1e+300");
  EXPECT_EQ(load_error(with("max = 1.8", "max = 11")),
            at + "width.max: must be within ±10 (a mouth measure over the eyes-to-nose distance), got 11");
  EXPECT_EQ(load_error(with("min = -0.02", "min = -10.5")),
            at + "protrusion.min: must be within ±10 (a mouth measure over the eyes-to-nose distance), got -10.5");
  const std::string v2 = with("version = 1", "version = 2");
  EXPECT_EQ(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = [0.5, 1e30]\n"),
            at + "identity.alpha[1]: not a number within ±30 (standard deviations of the model's identity)");
  EXPECT_THAT(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = [-30.5]\n"), HasSubstr("identity.alpha[0]"));
  EXPECT_EQ(load_error(v2 + "[identity]\nmodel_fingerprint = 7\nalpha = [-29.5, 8]\n"), "") << "a face, if unusual";
  EXPECT_EQ(load_error(with("performer = \"old\"", "performer = 'alice'")),
            at + "performer: must be \"old\", the performer it is loaded for; got \"alice\"");
  EXPECT_EQ(load_error(with("performer = \"old\"\n", "")),
            at + "performer: must be \"old\", the performer it is loaded for; got none");
}

/// `lipdrive process` with the ICT head and the profile of `bob` carrying `identity`, fitted to it.
test::CommandRun process_with_identity(const std::filesystem::path& dir, PerformerIdentity identity) {
  const std::filesystem::path ict = std::filesystem::path(test::kModelDir) / "ict_face_light.lpm";
  identity.model_fingerprint = identity_fingerprint(load_model_file(ict));
  PerformerProfile profile;
  profile.identity = identity;
  save_profile(dir / "bob.toml", "bob", profile);
  const std::filesystem::path config = dir / "lipdrive.toml";
  std::ofstream(config) << fmt::format(
      "[model]\nfile = \"{}\"\nlandmark_set = \"F5\"\n[performer]\nname = \"bob\"\nprofiles_dir = \"{}\"\n",
      ict.string(), dir.string());
  return test::run_command(fmt::format("{} process {} --config {} --out {}", test::kLipdrive, test::kClip.string(),
                                       config.string(), (dir / "out.csv").string()));
}

// The identity's fingerprint names the model, so a coefficient or a rest weight fewer (a value
// deleted by hand) shifts every later one onto another component: the fit quality halved.
TEST_F(ProfileFile, AnIdentityWithoutTheModelsCountsIsAnErrorNamingTheFileAndTheKey) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  PerformerIdentity identity;
  identity.components = 19;  // the ICT head has 20
  const test::CommandRun short_alpha = process_with_identity(dir_, identity);
  EXPECT_EQ(short_alpha.exit_code, 65) << short_alpha.output;
  EXPECT_THAT(short_alpha.output,
              ::testing::HasSubstr((dir_ / "bob.toml").string() +
                                   ": key identity.alpha: 19 numbers, but the model of its model_fingerprint has 20 "
                                   "identity components"));
  identity.components = 20;
  identity.expressions = 52;  // of 53
  const test::CommandRun short_rest = process_with_identity(dir_, identity);
  EXPECT_EQ(short_rest.exit_code, 65) << short_rest.output;
  EXPECT_THAT(short_rest.output, ::testing::HasSubstr(": key identity.rest_expression: 52 numbers, but the model of "
                                                      "its model_fingerprint has 53 expression shapes"));
}

}  // namespace
}  // namespace lipdrive
