#include "sim/simulated_camera.hpp"

#include "core/image_rotation.hpp"
#include "drivers/clock.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "command_run.hpp"
#include "exif_jpeg.hpp"
#include "variable_rate_clip.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <unistd.h>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

constexpr int kFrames = 20;
constexpr double kFps = 25;
constexpr milliseconds kLongTimeout{1000};

// A frame whose mean brightness encodes its index, so order can be checked after lossy coding.
cv::Mat numbered_frame(int index) {
  cv::Mat bgr(120, 160, CV_8UC3, cv::Scalar::all(10 + 10 * index));
  cv::putText(bgr, std::to_string(index), {20, 80}, cv::FONT_HERSHEY_SIMPLEX, 2, cv::Scalar(0, 0, 255), 3);
  return bgr;
}

int decoded_index(const cv::Mat& gray) {
  // Background level 10 + 10 i dominates the mean; the digits shift it by a few levels.
  cv::Mat corner = gray(cv::Rect(0, 0, 16, 16));
  return static_cast<int>(std::lround((cv::mean(corner)[0] - 10) / 10));
}

/// Replays `clip` as fast as it decodes: each of its kFrames frames in order, then a clean end
/// with no error reported.
void expect_every_frame_then_a_clean_end(const fs::path& clip) {
  SimulatedCamera camera({.input = clip});
  Frame frame;
  int delivered = 0;
  GrabStatus status;
  while ((status = camera.grab(frame, kLongTimeout)) == GrabStatus::kFrame)
    EXPECT_EQ(decoded_index(frame.gray), delivered++);
  EXPECT_EQ(delivered, kFrames);
  EXPECT_EQ(status, GrabStatus::kEndOfStream);
  EXPECT_FALSE(camera.last_error().has_value()) << camera.last_error().value_or("");
}

class SimulatedCameraTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lipdrive_simcam_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write_video(int frames) {
    const auto path = dir_ / "clip.avi";
    cv::VideoWriter writer(path.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), kFps, {160, 120});
    EXPECT_TRUE(writer.isOpened());
    for (int i = 0; i < frames; ++i) writer.write(numbered_frame(i));
    return path;
  }

  // `video` with sound a second longer than its picture, coded by `codecs` (FFmpeg's options,
  // the container's -f among them) into `out`.
  static void add_longer_sound(const fs::path& video, const std::string& codecs, const fs::path& out) {
    const test::CommandRun run = test::run_command(
        fmt::format("ffmpeg -v error -y -i {} -f lavfi -i sine=duration={} -map 0:v -map 1:a -q:v 2 {} {}",
                    video.string(), kFrames / kFps + 1, codecs, out.string()));
    ASSERT_EQ(run.exit_code, 0) << run.output;
  }

  fs::path dir_;
};

TEST_F(SimulatedCameraTest, ReplaysAVideoInOrderWithIncreasingTimestamps) {
  const auto path = write_video(kFrames);
  SimulatedCamera camera({.input = path});
  EXPECT_DOUBLE_EQ(camera.frame_rate(), kFps);

  Frame frame;
  std::int64_t last_time = 0;
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << "frame " << i;
    EXPECT_EQ(frame.sequence, static_cast<std::uint64_t>(i));
    EXPECT_EQ(frame.gray.type(), CV_8UC1);
    EXPECT_EQ(frame.gray.size(), cv::Size(160, 120));
    EXPECT_EQ(decoded_index(frame.gray), i);
    EXPECT_GT(frame.capture_time_ns, last_time);
    EXPECT_NEAR(frame.media_time_s, i / kFps, 1e-9);
    EXPECT_EQ(frame.source, path.string());
    last_time = frame.capture_time_ns;
  }
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
  EXPECT_FALSE(camera.last_error().has_value());
}

TEST_F(SimulatedCameraTest, RealTimePacingTakesTheRecordingsDuration) {
  const auto path = write_video(kFrames);
  SimulatedCamera camera({.input = path, .real_time = true});
  Frame frame;
  const auto start = std::chrono::steady_clock::now();
  int delivered = 0;
  while (camera.grab(frame, kLongTimeout) == GrabStatus::kFrame) ++delivered;
  const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(delivered, kFrames);
  // Frame 0 is due at once, frame N-1 at (N-1)/fps; the end is reported one period later.
  EXPECT_NEAR(elapsed_s, kFrames / kFps, 0.3 * kFrames / kFps);
}

TEST_F(SimulatedCameraTest, RealTimeReportsTimeoutWhenTheNextFrameIsNotDue) {
  const auto path = write_video(3);
  SimulatedCamera camera({.input = path, .real_time = true, .image_frame_rate = 25});
  Frame frame;
  ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  // The next frame is due 40 ms later: a 5 ms wait cannot get it.
  EXPECT_EQ(camera.grab(frame, milliseconds(5)), GrabStatus::kTimeout);
  ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  EXPECT_EQ(frame.sequence, 1u);
}

TEST_F(SimulatedCameraTest, LoopWrapsToTheFirstFrame) {
  const auto path = write_video(5);
  SimulatedCamera camera({.input = path, .loop = true});
  Frame frame;
  for (int i = 0; i < 12; ++i) {
    ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << "grab " << i;
    EXPECT_EQ(frame.sequence, static_cast<std::uint64_t>(i));
    EXPECT_EQ(decoded_index(frame.gray), i % 5);
    EXPECT_NEAR(frame.media_time_s, (i % 5) / kFps, 1e-9);
  }
}

TEST_F(SimulatedCameraTest, ReplaysAFolderInFileNameOrder) {
  // Written out of order, with a non-image file that must be skipped.
  for (const int i : {2, 0, 1}) cv::imwrite((dir_ / ("img_" + std::to_string(i) + ".png")).string(), numbered_frame(i));
  std::ofstream(dir_ / "notes.txt") << "not an image\n";

  SimulatedCamera camera({.input = dir_, .image_frame_rate = 10});
  EXPECT_DOUBLE_EQ(camera.frame_rate(), 10);
  Frame frame;
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
    EXPECT_EQ(frame.source, "img_" + std::to_string(i) + ".png");
    EXPECT_EQ(decoded_index(frame.gray), i);
    EXPECT_NEAR(frame.media_time_s, i / 10.0, 1e-12);
  }
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
}

TEST_F(SimulatedCameraTest, AnUndecodableImageInAFolderIsOneCorruptFrame) {
  cv::imwrite((dir_ / "a.png").string(), numbered_frame(0));
  std::ofstream(dir_ / "b.png") << "garbage";
  cv::imwrite((dir_ / "c.png").string(), numbered_frame(2));

  SimulatedCamera camera({.input = dir_});
  Frame frame;
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kCorrupt);
  ASSERT_TRUE(camera.last_error().has_value());
  EXPECT_NE(camera.last_error()->find("b.png"), std::string::npos);
  ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  EXPECT_EQ(frame.source, "c.png");
  EXPECT_EQ(frame.sequence, 2u);  // the corrupt frame leaves a gap
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
}

TEST_F(SimulatedCameraTest, ReplaysASingleImage) {
  const auto path = dir_ / "still.jpg";
  cv::imwrite(path.string(), numbered_frame(7));
  SimulatedCamera camera({.input = path});
  Frame frame;
  ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  EXPECT_EQ(frame.source, "still.jpg");
  EXPECT_EQ(decoded_index(frame.gray), 7);
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);

  SimulatedCamera looping({.input = path, .loop = true});
  for (int i = 0; i < 3; ++i) ASSERT_EQ(looping.grab(frame, kLongTimeout), GrabStatus::kFrame);
  EXPECT_EQ(frame.sequence, 2u);
}

TEST(ImageRotation, QuarterTurnsAreClockwiseAndKeepTheirBuffer) {
  const cv::Mat in = (cv::Mat_<std::uint8_t>(2, 3) << 1, 2, 3, 4, 5, 6);
  cv::Mat out;
  rotate_plane(in, out, Rotation::k90);  // the left column becomes the top row, read upwards
  EXPECT_EQ(cv::countNonZero(out != (cv::Mat_<std::uint8_t>(3, 2) << 4, 1, 5, 2, 6, 3)), 0) << out;
  const std::uint8_t* buffer = out.data;
  rotate_plane(in, out, Rotation::k90);
  EXPECT_EQ(out.data, buffer) << "a frame of the same size reuses the buffer";
  rotate_plane(in, out, Rotation::k180);
  EXPECT_EQ(cv::countNonZero(out != (cv::Mat_<std::uint8_t>(2, 3) << 6, 5, 4, 3, 2, 1)), 0) << out;
  rotate_plane(in, out, Rotation::k270);
  EXPECT_EQ(cv::countNonZero(out != (cv::Mat_<std::uint8_t>(3, 2) << 3, 6, 2, 5, 1, 4)), 0) << out;
  rotate_plane(in, out, Rotation::k0);
  EXPECT_EQ(cv::countNonZero(out != in), 0) << out;
  rotate_plane(cv::Mat(), out, Rotation::k90);
  EXPECT_TRUE(out.empty()) << "a monochrome camera's missing chroma stays missing";

  // Planes whose sides are and are not multiples of the 8 × 8 blocks, against OpenCV's turn.
  cv::RNG random(7);
  for (const cv::Size size : {cv::Size(640, 480), cv::Size(21, 13), cv::Size(8, 8), cv::Size(5, 1), cv::Size(3, 17)}) {
    cv::Mat plane(size, CV_8UC1), expected;
    random.fill(plane, cv::RNG::UNIFORM, 0, 256);
    for (const auto& [rotation, code] : {std::pair{Rotation::k90, cv::ROTATE_90_CLOCKWISE},
                                         std::pair{Rotation::k180, cv::ROTATE_180},
                                         std::pair{Rotation::k270, cv::ROTATE_90_COUNTERCLOCKWISE}}) {
      rotate_plane(plane, out, rotation);
      cv::rotate(plane, expected, code);
      ASSERT_EQ(out.size(), expected.size()) << size << " turned " << static_cast<int>(rotation);
      EXPECT_EQ(cv::countNonZero(out != expected), 0) << size << " turned " << static_cast<int>(rotation);
    }
  }
  const cv::Mat wide(40, 64, CV_8UC1, cv::Scalar(9));
  rotate_plane(wide(cv::Rect(3, 2, 33, 17)), out, Rotation::k90);  // rows apart by more than their width
  EXPECT_EQ(out.size(), cv::Size(17, 33));
  EXPECT_EQ(cv::countNonZero(out != 9), 0);

  for (const int degrees : {0, 90, 180, 270}) EXPECT_EQ(static_cast<int>(*rotation_from_degrees(degrees)), degrees);
  for (const int degrees : {-90, 45, 360}) EXPECT_FALSE(rotation_from_degrees(degrees)) << degrees;
}

TEST_F(SimulatedCameraTest, AConfiguredPictureLargerThanACamerasIsAConfigurationErrorNamingTheKey) {
  const auto path = dir_ / "tall.png";
  ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat(9000, 16, CV_8UC1, cv::Scalar(0))));
  Config config;
  config.camera.sim = {.input = path};
  try {
    make_source(config);
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(fmt::format(
                  "key camera.input: {}: pictures of 16×9000 pixels; at most 8192 on a side", path.string())),
              std::string::npos)
        << e.what();
  }
}

TEST_F(SimulatedCameraTest, TheConfiguredCameraDeliversItsFramesTurnedUpright) {
  const auto path = dir_ / "sideways.png";
  cv::imwrite(path.string(), numbered_frame(3));
  SimulatedCamera plain({.input = path});
  Frame upright;
  ASSERT_EQ(plain.grab(upright, kLongTimeout), GrabStatus::kFrame);

  Config config;
  config.camera.sim = {.input = path, .real_time = false, .loop = true};
  config.camera.rotation = Rotation::k90;
  const std::unique_ptr<FrameSource> camera = make_source(config);
  EXPECT_NE(camera->describe().find("turned 90°"), std::string::npos) << camera->describe();
  Frame frame;
  ASSERT_EQ(camera->grab(frame, kLongTimeout), GrabStatus::kFrame);
  cv::Mat expected;
  cv::rotate(upright.gray, expected, cv::ROTATE_90_CLOCKWISE);
  ASSERT_EQ(frame.gray.size(), expected.size());
  EXPECT_EQ(cv::countNonZero(frame.gray != expected), 0);
  cv::rotate(upright.cr, expected, cv::ROTATE_90_CLOCKWISE);
  ASSERT_EQ(frame.cr.size(), expected.size()) << "the chroma turns with the luma";
  EXPECT_EQ(cv::countNonZero(frame.cr != expected), 0);
  EXPECT_EQ(frame.source, "sideways.png");
  const std::uint8_t* buffer = frame.gray.data;
  ASSERT_EQ(camera->grab(frame, kLongTimeout), GrabStatus::kFrame);
  EXPECT_EQ(frame.gray.data, buffer) << "the next frame is turned into the same buffer";
}

TEST_F(SimulatedCameraTest, FramesAreShownAsTheirFileMeansThem) {
  // Quadrants of four grey levels and a number: mirrored or turned wrongly, it shows.
  cv::Mat upright(120, 160, CV_8UC3);
  const std::array<int, 4> levels{40, 100, 160, 220};
  for (int q = 0; q < 4; ++q)
    upright(cv::Rect((q % 2) * 80, (q / 2) * 60, 80, 60)).setTo(cv::Scalar::all(levels[static_cast<std::size_t>(q)]));
  cv::putText(upright, "3", {60, 80}, cv::FONT_HERSHEY_SIMPLEX, 2, cv::Scalar(0, 0, 255), 3);
  cv::Mat expected;
  cv::cvtColor(upright, expected, cv::COLOR_BGR2GRAY);
  // A phone's photo stores the picture as its sensor saw it and says how to show it: EXIF 7
  // (mirror, then turn a quarter clockwise) shows a picture stored mirrored after a quarter
  // turn anticlockwise.
  cv::Mat stored;
  cv::rotate(upright, stored, cv::ROTATE_90_COUNTERCLOCKWISE);
  cv::flip(stored, stored, 1);
  const fs::path single = dir_ / "phone.jpg", folder = dir_ / "photos";
  test::write_jpeg_with_orientation(single, stored, 7);
  fs::create_directories(folder);
  test::write_jpeg_with_orientation(folder / "a.jpg", stored, 7);
  cv::Mat turned_only;  // the same picture stored a quarter turn anticlockwise, EXIF 6
  cv::rotate(upright, turned_only, cv::ROTATE_90_COUNTERCLOCKWISE);
  test::write_jpeg_with_orientation(folder / "b.jpg", turned_only, 6);
  for (const fs::path& input : {single, folder}) {
    SimulatedCamera camera({.input = input});
    Frame frame;
    for (int i = 0; i < (input == folder ? 2 : 1); ++i) {
      ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << input;
      ASSERT_EQ(frame.gray.size(), expected.size()) << frame.source;
      cv::Mat difference;
      cv::absdiff(frame.gray, expected, difference);
      EXPECT_LT(cv::mean(difference)[0], 2.0) << frame.source;
      ASSERT_FALSE(frame.cr.empty());
      EXPECT_EQ(frame.cr.size(), cv::Size(expected.cols / 2, expected.rows / 2)) << "JPEG's 4:2:0 Cr, turned too";
    }
  }
}

void expect_source_error_naming(const fs::path& path) {
  try {
    SimulatedCamera camera({.input = path});
    FAIL() << "no SourceError for " << path;
  } catch (const SourceError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST_F(SimulatedCameraTest, UnusableInputsThrowSourceErrorNamingThePath) {
  expect_source_error_naming(dir_ / "missing.avi");
  const auto empty = dir_ / "empty";
  fs::create_directories(empty);
  expect_source_error_naming(empty);
  const auto text = dir_ / "readme.txt";
  std::ofstream(text) << "this is not a video\n";
  expect_source_error_naming(text);
  const auto fake_png = dir_ / "fake.png";
  std::ofstream(fake_png) << "this is not a png\n";
  expect_source_error_naming(fake_png);
}

TEST_F(SimulatedCameraTest, ATruncatedVideoYieldsFramesThenCorruptThenEnd) {
  const auto path = write_video(kFrames);
  fs::resize_file(path, fs::file_size(path) / 2);

  SimulatedCamera camera({.input = path});
  Frame frame;
  int delivered = 0;
  GrabStatus status;
  while ((status = camera.grab(frame, kLongTimeout)) == GrabStatus::kFrame) ++delivered;
  EXPECT_GT(delivered, 0);
  EXPECT_LT(delivered, kFrames);
  EXPECT_EQ(status, GrabStatus::kCorrupt);
  ASSERT_TRUE(camera.last_error().has_value());
  EXPECT_NE(camera.last_error()->find(path.string()), std::string::npos);
  EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
}

// A looping replay (the daemon's) of a damaged file goes on over the frames before the damage:
// one corrupt frame where it is met, then the first frame again, pass after pass.
TEST_F(SimulatedCameraTest, ALoopingReplayOfATruncatedVideoStartsOverAtItsDamage) {
  const auto path = write_video(kFrames);
  fs::resize_file(path, fs::file_size(path) / 2);
  SimulatedCamera camera({.input = path, .loop = true});
  Frame frame;
  int corrupt = 0, frames = 0;
  std::uint64_t last_sequence = 0;
  for (int i = 0; i < 3 * kFrames; ++i) {
    const GrabStatus status = camera.grab(frame, kLongTimeout);
    ASSERT_NE(status, GrabStatus::kEndOfStream) << "grab " << i;
    corrupt += status == GrabStatus::kCorrupt;
    if (status != GrabStatus::kFrame) continue;
    if (frames++ > 0) EXPECT_GT(frame.sequence, last_sequence);
    last_sequence = frame.sequence;
  }
  EXPECT_GE(corrupt, 2) << "the damage met in each pass";
  EXPECT_GT(frames, 2 * corrupt);

  // In real time the next pass starts right after the damage, not at the length the file
  // states (Matroska's header keeps the whole length; half of it is missing): two passes take
  // about the readable half twice.
  const fs::path whole = dir_ / "whole.mkv", cut = dir_ / "cut.mkv";
  const test::CommandRun made = test::run_command(
      fmt::format("ffmpeg -v error -y -i {} -c:v mpeg4 -f matroska {}", write_video(kFrames).string(), whole.string()));
  ASSERT_EQ(made.exit_code, 0) << made.output;
  fs::copy_file(whole, cut);
  fs::resize_file(cut, fs::file_size(whole) / 2);
  SimulatedCamera paced({.input = cut, .real_time = true, .loop = true});
  const auto start = std::chrono::steady_clock::now();
  for (int passes = 0; passes < 2;)
    if (const GrabStatus status = paced.grab(frame, kLongTimeout); status == GrabStatus::kCorrupt)
      ++passes;
    else
      ASSERT_NE(status, GrabStatus::kEndOfStream);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_LT(seconds, 1.6 * kFrames / kFps) << "two passes waited for the missing half";
}

// What is shown of a clip is its picture: sound running on after the last frame, or frames an
// MP4's edit list leaves unshown (a cut with -c copy between keyframes), are not damage.
TEST_F(SimulatedCameraTest, AVideoWhoseSoundOutlastsItsPictureEndsCleanly) {
  const auto source = write_video(kFrames);
  for (const std::string codecs :
       {"-c:v mpeg4 -c:a aac -f matroska", "-c:v mpeg1video -c:a mp2 -f mpeg", "-c:v mpeg2video -c:a mp2 -f mpegts",
        "-c:v mpeg4 -c:a aac -f mp4", "-c:v mjpeg -c:a pcm_s16le -f avi", "-c:v flv -c:a aac -f flv"}) {
    SCOPED_TRACE(codecs);
    const fs::path clip = dir_ / "longer_sound";
    ASSERT_NO_FATAL_FAILURE(add_longer_sound(source, codecs, clip));
    expect_every_frame_then_a_clean_end(clip);
  }
}

// A looping replay restarts where the clip's simulated sound, looping at duration_s(), does: at
// the recording's length, its sound's where that outlasts the picture, whatever the frames' rate.
TEST_F(SimulatedCameraTest, ALoopingReplayRestartsItsPictureWhereItsSoundLoops) {
  const auto source = write_video(kFrames);
  const fs::path variable = dir_ / "variable.mkv";
  const test::CommandRun made = test::variable_rate_clip(source, kFrames, variable);
  ASSERT_EQ(made.exit_code, 0) << made.output;
  const double sound_s = kFrames / kFps + 1;
  for (const auto& [video, codecs] : {std::pair{source, std::string("-c:v mpeg4 -c:a aac -f matroska")},
                                      std::pair{variable, std::string("-c:v copy -c:a aac -f matroska")}}) {
    SCOPED_TRACE(codecs);
    const fs::path clip = dir_ / "longer_sound.mkv";
    ASSERT_NO_FATAL_FAILURE(add_longer_sound(video, codecs, clip));
    ReplayClock clock;
    SimulatedCamera camera({.input = clip, .real_time = true, .loop = true}, &clock);
    const double pass_s = camera.duration_s();
    EXPECT_NEAR(pass_s, sound_s, 2 / kFps);  // the sound's, with the AAC encoder's priming and padding
    EXPECT_EQ(clock.loop_s(), pass_s) << "the sound loops where the picture does";
    ReplayClock once;
    SimulatedCamera({.input = clip, .real_time = true, .loop = false}, &once);
    EXPECT_EQ(once.loop_s(), 0) << "a replay that plays once";
    Frame frame;
    for (int i = 0; i < kFrames; ++i) ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << "frame " << i;
    // The picture holds its last frame through the sound's tail: the next frame is the first
    // again, due where the sound starts over.
    ASSERT_EQ(camera.grab(frame, milliseconds(2000)), GrabStatus::kFrame);
    EXPECT_EQ(decoded_index(frame.gray), 0);
    EXPECT_NEAR(frame.media_time_s, 0, 1e-9);
    const double delivered_s = static_cast<double>(frame.capture_time_ns - clock.start_ns()) * 1e-9;
    EXPECT_GE(delivered_s, pass_s - 0.001);
    EXPECT_LT(delivered_s, pass_s + 1 / kFps);
    EXPECT_EQ(frame.sequence, static_cast<std::uint64_t>(std::llround(pass_s * kFps)));
  }
}

TEST_F(SimulatedCameraTest, AnMp4CutWithoutReencodingShowsItsCutAndEndsCleanly) {
  // Keyframes 0 and 10; the cut from frame 3 to 12 keeps frames 0-2 for the decoder, which
  // the edit list leaves unshown.
  const auto source = write_video(kFrames);
  const fs::path whole = dir_ / "whole.mp4", cut = dir_ / "cut.mp4";
  ASSERT_EQ(
      test::run_command(fmt::format("ffmpeg -v error -y -i {} -c:v mpeg4 -q:v 2 -g 10 -sc_threshold 1000000000 {}",
                                    source.string(), whole.string()))
          .exit_code,
      0);
  ASSERT_EQ(test::run_command(
                fmt::format("ffmpeg -v error -y -ss 0.12 -i {} -t 0.4 -c copy {}", whole.string(), cut.string()))
                .exit_code,
            0);
  SimulatedCamera camera({.input = cut});
  Frame frame;
  int delivered = 0;
  GrabStatus status;
  while ((status = camera.grab(frame, kLongTimeout)) == GrabStatus::kFrame)
    EXPECT_EQ(decoded_index(frame.gray), 3 + delivered++);
  EXPECT_EQ(delivered, 10);
  EXPECT_EQ(status, GrabStatus::kEndOfStream);
  EXPECT_FALSE(camera.last_error().has_value()) << camera.last_error().value_or("");
}

// A file cut short is damage, its sound running on or not: the frames before the cut, then
// kCorrupt naming the file, then the end. Told by the frames its container states (a Matroska
// track's DURATION, an MP4's or AVI's frame count) or, in an FLV file, which states none, by
// the packet the cut falls inside.
TEST_F(SimulatedCameraTest, AVideoCutShortYieldsFramesThenCorruptThenEnd) {
  const auto source = write_video(kFrames);
  for (const std::string codecs : {"-c:v mpeg4 -c:a aac -f matroska", "-c:v mpeg4 -c:a aac -movflags +faststart -f mp4",
                                   "-c:v mjpeg -c:a pcm_s16le -f avi", "-c:v flv -c:a aac -f flv"}) {
    SCOPED_TRACE(codecs);
    const fs::path clip = dir_ / "cut_short";
    ASSERT_NO_FATAL_FAILURE(add_longer_sound(source, codecs, clip));
    fs::resize_file(clip, fs::file_size(clip) / 2);
    SimulatedCamera camera({.input = clip});
    Frame frame;
    int delivered = 0;
    GrabStatus status;
    while ((status = camera.grab(frame, kLongTimeout)) == GrabStatus::kFrame) ++delivered;
    EXPECT_LT(delivered, kFrames);
    EXPECT_EQ(status, GrabStatus::kCorrupt);
    ASSERT_TRUE(camera.last_error().has_value());
    EXPECT_NE(camera.last_error()->find(clip.string()), std::string::npos) << *camera.last_error();
    EXPECT_NE(camera.last_error()->find("damaged or truncated"), std::string::npos) << *camera.last_error();
    EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
  }
}

// A file cut inside the sound that runs on after its last frame shows its whole picture: every
// frame, then a clean end (what a replay shows is its picture, and none of it is missing).
TEST_F(SimulatedCameraTest, AVideoCutInsideTheSoundAfterItsLastFrameEndsCleanly) {
  const auto source = write_video(kFrames);
  for (const std::string codecs : {"-c:v mpeg4 -c:a aac -f matroska", "-c:v flv -c:a aac -f flv"}) {
    SCOPED_TRACE(codecs);
    const fs::path clip = dir_ / "cut_in_sound";
    ASSERT_NO_FATAL_FAILURE(add_longer_sound(source, codecs, clip));
    // Where each packet lies in the file: the cut falls inside a sound packet after the last frame's.
    const test::CommandRun packets = test::run_command(
        fmt::format("ffprobe -v error -show_entries packet=codec_type,size,pos -of csv=p=0 {}", clip.string()));
    ASSERT_EQ(packets.exit_code, 0) << packets.output;
    std::istringstream lines(packets.output);
    std::int64_t last_video_end = 0, cut = 0;
    for (std::string line; std::getline(lines, line);) {
      char type[16] = {};
      long long size = 0, pos = 0;
      if (std::sscanf(line.c_str(), "%15[^,],%lld,%lld", type, &size, &pos) != 3) continue;
      if (std::string_view(type) == "video") {
        last_video_end = pos + size;
        cut = 0;
      } else if (cut == 0 && pos >= last_video_end && last_video_end > 0) {
        cut = pos + size / 2;  // the first sound packet after the last frame's
      }
    }
    ASSERT_GT(cut, last_video_end) << packets.output;
    fs::resize_file(clip, static_cast<std::uintmax_t>(cut));
    expect_every_frame_then_a_clean_end(clip);
  }
}

TEST_F(SimulatedCameraTest, AFrameTheRecorderDroppedIsAGapInTimeNotDamage) {
  // The recording without its frame 3, timestamps kept (FFmpeg as a recorder that dropped a
  // frame writes it): an AVI keeps the slot as an empty chunk and declares 20 frames, a
  // Matroska file has a gap in its timestamps and a duration of 20 frames. 19 pictures are
  // in each.
  const auto source = write_video(kFrames);
  for (const char* container : {"avi", "mkv"}) {
    SCOPED_TRACE(container);
    const fs::path gapped = dir_ / fmt::format("gapped.{}", container);
    ASSERT_EQ(test::run_command(fmt::format("ffmpeg -v error -y -i {} -vf \"select='not(eq(n\\,3))'\" "
                                            "-fps_mode passthrough -c:v mjpeg {}",
                                            source.string(), gapped.string()))
                  .exit_code,
              0);
    // Replayed as fast as it decodes and in real time: the slot is a gap in the sequence
    // numbers, as a camera's lost frame is, and in real time a gap in time, so that the frames
    // after it are shown when their sound is heard (each no earlier than its place on the
    // file's timeline after the replay began).
    for (const bool real_time : {false, true}) {
      SCOPED_TRACE(real_time ? "in real time" : "as fast as it decodes");
      SimulatedCamera camera({.input = gapped, .real_time = real_time, .replay_rate = real_time ? 100.0 : 0.0});
      const double period_s = real_time ? 1.0 / 100 : 1.0 / kFps;
      const std::int64_t began_ns = monotonic_ns();
      Frame frame;
      for (int i = 0; i < kFrames; ++i) {
        if (i == 3) continue;
        ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << "frame " << i;
        EXPECT_EQ(decoded_index(frame.gray), i);
        EXPECT_EQ(frame.sequence, static_cast<std::uint64_t>(i));
        EXPECT_NEAR(frame.media_time_s, i * period_s, 1e-6) << "frame " << i;
        if (real_time) {
          EXPECT_GE(frame.capture_time_ns - began_ns, std::llround(i * period_s * 1e9)) << "frame " << i;
        }
      }
      EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
      EXPECT_FALSE(camera.last_error().has_value()) << camera.last_error().value_or("");
    }
  }
}

TEST_F(SimulatedCameraTest, AVariableRateClipIsReplayedAtItsFramesOwnTimes) {
  // 25, then 50, then 25 frames per second; the file states 25.
  const fs::path clip = dir_ / "variable.mkv";
  const test::CommandRun made = test::variable_rate_clip(write_video(kFrames), kFrames, clip);
  ASSERT_EQ(made.exit_code, 0) << made.output;
  const std::vector<double> times = test::variable_rate_times(kFrames);
  // As fast as it decodes: each frame's media time is its own; the sequence numbers stay unique
  // and increasing.
  {
    SimulatedCamera camera({.input = clip, .real_time = false});
    EXPECT_DOUBLE_EQ(camera.frame_rate(), kFps);
    Frame frame;
    std::int64_t last_sequence = -1;
    for (int i = 0; i < kFrames; ++i) {
      ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << "frame " << i;
      EXPECT_EQ(decoded_index(frame.gray), i);
      EXPECT_GT(static_cast<std::int64_t>(frame.sequence), last_sequence) << "frame " << i;
      last_sequence = static_cast<std::int64_t>(frame.sequence);
      EXPECT_NEAR(frame.media_time_s, times[i], 0.001) << "frame " << i;
    }
    EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
  }
  // In real time at its own rate each frame is delivered at its own time (its sound is heard
  // then), the frames at 50 fps too: never early, and late by no more than a wake-up. The
  // lateness is the best of up to three replays: a host's pause can hold up one frame of one
  // replay (the CI's asan lane shares two cores), while a frame read at the slot the one before
  // suggests is 20 ms late in every replay.
  double best_lateness_s = 1;
  for (int replay = 0; replay < 3 && best_lateness_s >= 0.015; ++replay) {
    SimulatedCamera camera({.input = clip, .real_time = true});
    const std::int64_t began_ns = monotonic_ns();
    Frame frame;
    double lateness_s = 0;
    for (int i = 0; i < kFrames; ++i) {
      ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << "frame " << i;
      EXPECT_EQ(decoded_index(frame.gray), i);
      EXPECT_NEAR(frame.media_time_s, times[i], 0.001) << "frame " << i;
      const double delivered_s = static_cast<double>(frame.capture_time_ns - began_ns) * 1e-9;
      EXPECT_GE(delivered_s, times[i] - 0.001) << "frame " << i;
      lateness_s = std::max(lateness_s, delivered_s - times[i]);
    }
    EXPECT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kEndOfStream);
    best_lateness_s = std::min(best_lateness_s, lateness_s);
  }
  EXPECT_LT(best_lateness_s, 0.015);
  // At a replay rate of its own, its frames come at that rate whatever their times, and their
  // media times are the replay's.
  SimulatedCamera camera({.input = clip, .replay_rate = 100});
  Frame frame;
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << "frame " << i;
    EXPECT_NEAR(frame.media_time_s, static_cast<double>(frame.sequence) / 100, 1e-9) << "frame " << i;
  }
}

// Fault injection (the pipeline's tests of a misbehaving camera rely on these).

TEST_F(SimulatedCameraTest, InjectedDropsLeaveSequenceGapsAndCorruptFramesAreReported) {
  const auto path = write_video(kFrames);
  SimulatedCameraOptions options{.input = path};
  options.faults.drop_every = 4;
  options.faults.corrupt_every = 5;
  SimulatedCamera camera(options);
  Frame frame;
  int frames = 0, dropped = 0, corrupt = 0;
  for (int n = 1; n <= kFrames; ++n) {
    const GrabStatus status = camera.grab(frame, kLongTimeout);
    if (n % 4 == 0) {
      EXPECT_EQ(status, GrabStatus::kTimeout) << "frame " << n << " is dropped";
      ++dropped;
    } else if (n % 5 == 0) {
      EXPECT_EQ(status, GrabStatus::kCorrupt) << "frame " << n;
      ASSERT_TRUE(camera.last_error().has_value());
      EXPECT_NE(camera.last_error()->find("injected fault"), std::string::npos);
      ++corrupt;
    } else {
      ASSERT_EQ(status, GrabStatus::kFrame) << "frame " << n;
      EXPECT_EQ(frame.sequence, static_cast<std::uint64_t>(n - 1)) << "dropped frames leave gaps";
      EXPECT_EQ(decoded_index(frame.gray), n - 1);
      ++frames;
    }
  }
  EXPECT_EQ(dropped, 5);
  EXPECT_EQ(corrupt, 3);
  EXPECT_EQ(frames, 12);
}

TEST_F(SimulatedCameraTest, InjectedStallDelaysTheNextFrame) {
  const auto path = write_video(kFrames);
  SimulatedCameraOptions options{.input = path};
  options.faults.stall_every = 2;
  options.faults.stall = milliseconds(150);
  SimulatedCamera camera(options);
  Frame frame;
  ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(camera.grab(frame, milliseconds(20)), GrabStatus::kTimeout);
  ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  EXPECT_GE(std::chrono::steady_clock::now() - start, milliseconds(140));
  EXPECT_EQ(decoded_index(frame.gray), 2);
}

TEST_F(SimulatedCameraTest, InjectedDisconnectLastsItsTimeThenFramesResume) {
  const auto path = write_video(kFrames);
  SimulatedCameraOptions options{.input = path};
  options.faults.disconnect_after = 3;
  options.faults.reconnect = milliseconds(150);
  SimulatedCamera camera(options);
  Frame frame;
  for (int i = 0; i < 3; ++i) ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame);
  const auto start = std::chrono::steady_clock::now();
  int disconnected = 0;
  GrabStatus status;
  while ((status = camera.grab(frame, milliseconds(20))) == GrabStatus::kDisconnected) ++disconnected;
  ASSERT_EQ(status, GrabStatus::kFrame);
  EXPECT_GE(disconnected, 5);
  EXPECT_GE(std::chrono::steady_clock::now() - start, milliseconds(140));
  EXPECT_EQ(decoded_index(frame.gray), 3);
  // Once only.
  for (int i = 4; i < kFrames; ++i) ASSERT_EQ(camera.grab(frame, kLongTimeout), GrabStatus::kFrame) << i;
}

}  // namespace
}  // namespace lipdrive
