// Pictures through FFmpeg's libraries (drivers/video_file.hpp, drivers/image_codec.hpp),
// checked against OpenCV's own codecs, which the tests still link: the luma the tracker sees
// from a replayed clip, an image, a camera's MJPEG frame; the JPEG previews and PNG files.
#include "drivers/ffmpeg_log.hpp"
#include "drivers/image_codec.hpp"
#include "drivers/video_file.hpp"
#include "command_run.hpp"
#include "exif_jpeg.hpp"
#include "fixture_paths.hpp"
#include "variable_rate_clip.hpp"

#include <gmock/gmock.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

double mean_abs_difference(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat difference;
  cv::absdiff(a, b, difference);
  return cv::mean(difference)[0];
}

/// Runs `ffmpeg -v error -y ARGUMENTS`; a failure fails the test (wrap in ASSERT_NO_FATAL_FAILURE).
void ffmpeg(const std::string& arguments) {
  const test::CommandRun run = test::run_command("ffmpeg -v error -y " + arguments);
  ASSERT_EQ(run.exit_code, 0) << run.output;
}

/// A BGR test card: gradients, edges and text, so codecs have something to get wrong.
cv::Mat test_card() {
  cv::Mat bgr(240, 320, CV_8UC3);
  for (int y = 0; y < bgr.rows; ++y)
    for (int x = 0; x < bgr.cols; ++x)
      bgr.at<cv::Vec3b>(y, x) = {static_cast<uchar>(x * 255 / 319), static_cast<uchar>(y * 255 / 239),
                                 static_cast<uchar>((x + y) % 256)};
  cv::rectangle(bgr, {40, 40, 120, 80}, cv::Scalar(255, 255, 255), cv::FILLED);
  cv::putText(bgr, "lipdrive", {60, 200}, cv::FONT_HERSHEY_SIMPLEX, 1.5, cv::Scalar(0, 0, 0), 3);
  return bgr;
}

cv::Mat gray_of(const cv::Mat& bgr) {
  cv::Mat gray;
  cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
  return gray;
}

/// A plane as its orientation means it to be seen, by OpenCV's own flip and rotate.
cv::Mat shown(const cv::Mat& plane, DisplayOrientation orientation) {
  cv::Mat out = plane.clone();
  if (orientation.mirrored) cv::flip(out, out, 1);
  if (orientation.turn == Rotation::k90) cv::rotate(out, out, cv::ROTATE_90_CLOCKWISE);
  if (orientation.turn == Rotation::k180) cv::rotate(out, out, cv::ROTATE_180);
  if (orientation.turn == Rotation::k270) cv::rotate(out, out, cv::ROTATE_90_COUNTERCLOCKWISE);
  return out;
}

/// Reads `file` to its end: the frames read into `frames`, those lost into `lost`, and what
/// damage() says there.
std::string read_to_end(const fs::path& file, int& frames, std::optional<std::int64_t>* lost = nullptr) {
  VideoFile video(file);
  cv::Mat gray, cr;
  frames = 0;
  while (video.read(gray, cr)) ++frames;
  if (lost != nullptr) *lost = video.lost_frames();
  return video.damage();
}

class MediaFilesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("lipdrive_media_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// The talking-face clip's first `frames` frames as an MPEG program stream of MPEG-1 video
  /// (as GRID's clips are), `name` in the test's folder.
  fs::path mpeg_program_stream(int frames, const std::string& name) {
    const fs::path clip = dir_ / name;
    ffmpeg(fmt::format("-i {} -frames:v {} -an -c:v mpeg1video -q:v 4 -f mpeg {}", test::kClip.string(), frames,
                       clip.string()));
    return clip;
  }

  fs::path dir_;
};

TEST_F(MediaFilesTest, AClipsLumaIsWhatOpenCvsDecoderGives) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  VideoFile video(test::kClip);
  cv::VideoCapture reference(test::kClip.string(), cv::CAP_FFMPEG);
  ASSERT_TRUE(reference.isOpened());
  EXPECT_DOUBLE_EQ(video.frame_rate(), reference.get(cv::CAP_PROP_FPS));
  EXPECT_EQ(video.frame_count(), static_cast<std::int64_t>(reference.get(cv::CAP_PROP_FRAME_COUNT)));
  cv::Mat gray, cr, bgr;
  int frames = 0;
  double worst = 0;
  while (reference.read(bgr)) {
    ASSERT_TRUE(video.read(gray, cr)) << "frame " << frames;
    ASSERT_EQ(gray.size(), bgr.size());
    ASSERT_EQ(gray.type(), CV_8UC1);
    worst = std::max(worst, mean_abs_difference(gray, gray_of(bgr)));
    ++frames;
  }
  EXPECT_FALSE(video.read(gray, cr)) << "both end together";
  EXPECT_EQ(frames, video.frame_count());
  // Full-range luma either way; OpenCV goes through BGR and rounds twice.
  EXPECT_LT(worst, 1.0) << "mean absolute luma difference, worst frame";
}

// A variable-rate clip's frames at 25, 50 and 25 fps: each frame read carries its own time as
// ffprobe reads it and as it was given, not its slot at the one rate the file states, in
// Matroska (25 fps stated) and MP4 (50 fps stated); the slots stay unique and increasing.
TEST_F(MediaFilesTest, AVariableRateClipsFramesCarryTheirOwnTimes) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  constexpr int kFrames = 40;
  const std::vector<double> given = test::variable_rate_times(kFrames);
  for (const char* container : {"mkv", "mp4"}) {
    SCOPED_TRACE(container);
    const fs::path clip = dir_ / fmt::format("variable.{}", container);
    const test::CommandRun made = test::variable_rate_clip(test::kClip, kFrames, clip);
    ASSERT_EQ(made.exit_code, 0) << made.output;
    const std::vector<double> probed = test::ffprobe_frame_times(clip);
    ASSERT_EQ(probed.size(), given.size());
    VideoFile video(clip);
    cv::Mat gray, cr;
    std::int64_t last_index = -1;
    for (int i = 0; i < kFrames; ++i) {
      ASSERT_TRUE(video.read(gray, cr)) << "frame " << i;
      ASSERT_TRUE(video.frame_time_s().has_value()) << "frame " << i;
      EXPECT_NEAR(*video.frame_time_s(), probed[i], 0.001) << "frame " << i;
      EXPECT_NEAR(*video.frame_time_s(), given[i], 0.001) << "frame " << i;
      EXPECT_GT(video.frame_index(), last_index) << "frame " << i;
      last_index = video.frame_index();
    }
    EXPECT_FALSE(video.read(gray, cr));
    EXPECT_EQ(video.damage(), "");
  }
}

// A variable-rate Matroska clip (25 fps stated) that ends slower than its stated rate, a frame
// every 120 ms, its last shown for 150 ms: read whole, it ends cleanly, though its DURATION
// (1.83 s) over the stated rate counts more slots (45) than its frames reach (43).
TEST_F(MediaFilesTest, AVariableRateMatroskaClipEndingSlowerIsWholeWhereItsFramesReachItsDuration) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  constexpr int kFrames = 40, kFast = 30;
  const fs::path clip = dir_ / "slow_end.mkv";
  // As test::variable_rate_clip() makes its clip: the frames given new times, every one kept.
  const test::CommandRun made = test::run_command(fmt::format(
      "ffmpeg -v error -y -i {} -frames:v {} -an -vf \"settb=1/1000,setpts='20*min(N\\,{})+120*max(N-{}\\,0)'\" "
      "-fps_mode passthrough -enc_time_base 1/1000 -c:v mjpeg -q:v 3 "
      "-bsf:v \"setts=duration=if(eq(N\\,{})\\,150\\,DURATION)\" {}",
      test::kClip.string(), kFrames, kFast, kFast, kFrames - 1, clip.string()));
  ASSERT_EQ(made.exit_code, 0) << made.output;
  {
    VideoFile video(clip);
    EXPECT_DOUBLE_EQ(video.frame_rate(), 25);
  }
  int frames = 0;
  EXPECT_EQ(read_to_end(clip, frames), "");
  EXPECT_EQ(frames, kFrames);
}

// An MPEG program stream (GRID's clips) states no length, and its packets reach the decoder
// through FFmpeg's parser, which drops the demuxer's mark on a packet the file cuts short: cut
// inside a picture, it is told by the decoder patching up that last picture. Whole, it ends
// cleanly.
TEST_F(MediaFilesTest, AnMpegProgramStreamCutInsideAPictureIsDamaged) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  constexpr int kFrames = 50;
  fs::path whole;
  ASSERT_NO_FATAL_FAILURE(whole = mpeg_program_stream(kFrames, "whole.mpg"));
  const fs::path cut = dir_ / "cut.mpg";
  int frames = 0;
  EXPECT_EQ(read_to_end(whole, frames), "");
  EXPECT_EQ(frames, kFrames);
  fs::copy_file(whole, cut);
  fs::resize_file(cut, fs::file_size(whole) / 2);
  std::optional<std::int64_t> lost;
  EXPECT_EQ(read_to_end(cut, frames, &lost), "the file ends inside its last picture");
  EXPECT_GT(frames, 5);
  EXPECT_LT(frames, kFrames);
  EXPECT_EQ(lost, std::nullopt) << "the stream does not say how long it was";
}

// Garbage in the middle of an MPEG program stream: the demuxer finds its way past it, and the
// frames it overwrote are a jump in the timestamps, which such a stream (a frame coded every
// period) has nowhere else. Read as a recorder's dropped frames, they went unnoticed.
TEST_F(MediaFilesTest, FramesGarbageTookFromAnMpegProgramStreamAreMissingNotDropped) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  constexpr int kFrames = 50;
  fs::path clip;
  ASSERT_NO_FATAL_FAILURE(clip = mpeg_program_stream(kFrames, "garbled.mpg"));
  const std::uintmax_t size = fs::file_size(clip);
  std::mt19937 random(7);
  std::string garbage(size / 5, '\0');
  for (char& byte : garbage) byte = static_cast<char>(random());
  std::fstream file(clip, std::ios::in | std::ios::out | std::ios::binary);
  file.seekp(static_cast<std::streamoff>(size * 2 / 5));
  file.write(garbage.data(), static_cast<std::streamsize>(garbage.size()));
  file.close();
  int frames = 0;
  std::optional<std::int64_t> lost;
  EXPECT_THAT(read_to_end(clip, frames, &lost), HasSubstr("frames are missing where its timestamps jump"));
  EXPECT_LT(frames, kFrames);
  EXPECT_EQ(lost, kFrames - frames);
}

TEST_F(MediaFilesTest, ImagesReadAsOpenCvReadsThem) {
  const cv::Mat card = test_card();
  const fs::path png = dir_ / "card.png", jpeg = dir_ / "card.jpg", pgm = dir_ / "card.pgm";
  ASSERT_TRUE(cv::imwrite(png.string(), card));
  ASSERT_TRUE(cv::imwrite(jpeg.string(), card, {cv::IMWRITE_JPEG_QUALITY, 90}));
  ASSERT_TRUE(cv::imwrite(pgm.string(), gray_of(card)));
  const auto planes = [](const fs::path& file) {
    std::pair<cv::Mat, cv::Mat> gray_cr;
    read_image(file, gray_cr.first, gray_cr.second);
    return gray_cr;
  };
  // Cr as OpenCV's BT.601 conversion of the decoded colour image gives it (its 4:2:0 plane
  // brought up to the image's size where JPEG coded it at half size).
  const auto cr_of = [](const fs::path& file, cv::Size size) {
    cv::Mat ycrcb, channels[3];
    cv::cvtColor(cv::imread(file.string(), cv::IMREAD_COLOR), ycrcb, cv::COLOR_BGR2YCrCb);
    cv::split(ycrcb, channels);
    cv::Mat cr;
    cv::resize(channels[1], cr, size, 0, 0, cv::INTER_AREA);
    return cr;
  };
  const auto [png_gray, png_cr] = planes(png);
  EXPECT_LT(mean_abs_difference(png_gray, cv::imread(png.string(), cv::IMREAD_GRAYSCALE)), 0.6);
  ASSERT_EQ(png_cr.size(), card.size());
  EXPECT_LT(mean_abs_difference(png_cr, cr_of(png, png_cr.size())), 1.0);
  const auto [jpeg_gray, jpeg_cr] = planes(jpeg);
  EXPECT_LT(mean_abs_difference(jpeg_gray, cv::imread(jpeg.string(), cv::IMREAD_GRAYSCALE)), 1.0);
  ASSERT_FALSE(jpeg_cr.empty());
  EXPECT_LT(mean_abs_difference(jpeg_cr, cr_of(jpeg, jpeg_cr.size())), 2.0);
  const auto [pgm_gray, pgm_cr] = planes(pgm);
  EXPECT_EQ(mean_abs_difference(pgm_gray, gray_of(card)), 0.0);
  EXPECT_TRUE(pgm_cr.empty()) << "a gray image has no colour";
}

TEST_F(MediaFilesTest, UnreadableImagesAreErrorsNamingTheFile) {
  const fs::path fake = dir_ / "fake.png";
  std::ofstream(fake) << "not an image\n";
  for (const fs::path& file : {fake, dir_ / "missing.png"}) {
    try {
      cv::Mat gray, cr;
      read_image(file, gray, cr);
      ADD_FAILURE() << file << " was read";
    } catch (const MediaError& e) {
      EXPECT_THAT(e.what(), HasSubstr(file.string()));
    }
  }
}

// A picture larger than kMaxPictureSide on a side is refused before it is decoded (a 249 KB
// PNG of 16000×16000 took 2.5 GB and 37 s), in an image, in a video, and where a video's
// pictures grow past it on the way; one of kMaxPictureSide is read.
TEST_F(MediaFilesTest, PicturesLargerThanACamerasAreRefusedNamingTheFileAndTheSize) {
  const auto refused = [](const fs::path& file, const std::string& size) {
    const std::string expected = fmt::format("{}: pictures of {} pixels; at most 8192 on a side", file.string(), size);
    try {
      VideoFile video(file);
      cv::Mat gray, cr;
      while (video.read(gray, cr)) {
      }
      ADD_FAILURE() << file << " was read";
    } catch (const MediaError& e) {
      EXPECT_EQ(e.what(), expected);
    }
  };
  const fs::path wide = dir_ / "wide.png", widest = dir_ / "widest.png";
  ASSERT_TRUE(cv::imwrite(wide.string(), cv::Mat(16, 9000, CV_8UC1, cv::Scalar(0))));
  refused(wide, "9000×16");
  ASSERT_TRUE(cv::imwrite(widest.string(), cv::Mat(16, kMaxPictureSide, CV_8UC1, cv::Scalar(0))));
  cv::Mat gray, cr;
  read_image(widest, gray, cr);
  EXPECT_EQ(gray.size(), cv::Size(kMaxPictureSide, 16));

  const fs::path tall = dir_ / "tall.mkv", small = dir_ / "small.mkv", list = dir_ / "list.txt",
                 grows = dir_ / "grows.mkv";
  ASSERT_NO_FATAL_FAILURE(
      ffmpeg(fmt::format("-f lavfi -i color=gray:s=16x9000:r=25:d=0.12 -pix_fmt gray -c:v png {}", tall.string())));
  refused(tall, "16×9000");
  // Joined to a clip of 16×16 pictures: the stream says 16×16, its fourth picture is 16×9000.
  ASSERT_NO_FATAL_FAILURE(
      ffmpeg(fmt::format("-f lavfi -i color=gray:s=16x16:r=25:d=0.12 -pix_fmt gray -c:v png {}", small.string())));
  std::ofstream(list) << fmt::format("file '{}'\nfile '{}'\n", small.string(), tall.string());
  ASSERT_NO_FATAL_FAILURE(ffmpeg(fmt::format("-f concat -safe 0 -i {} -c copy {}", list.string(), grows.string())));
  refused(grows, "16×9000");

  // More pixels than kMaxPictureSide² in a still: FFmpeg's probe, held to that many, does not
  // decode it either (a 16000×16000 PNG took 305 MB in the probe alone).
  const fs::path huge = dir_ / "huge.png";
  ASSERT_TRUE(cv::imwrite(huge.string(), cv::Mat(kMaxPictureSide + 8, kMaxPictureSide + 8, CV_8UC1, cv::Scalar(0))));
  try {
    VideoFile video(huge);
    ADD_FAILURE() << huge << " was opened";
  } catch (const MediaError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr(huge.string() + ": cannot read the picture's size: "));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("(at most 8192 on a side)"));
  }
}

TEST_F(MediaFilesTest, JpegDecoderGivesTheLumaAndCrAndNeverAStaleFrame) {
  const cv::Mat card = test_card();
  std::vector<uchar> bytes;
  ASSERT_TRUE(cv::imencode(".jpg", card, bytes, {cv::IMWRITE_JPEG_QUALITY, 90}));
  JpegDecoder decoder;
  cv::Mat gray, cr;
  ASSERT_TRUE(decoder.decode(bytes, gray, cr));
  EXPECT_LT(mean_abs_difference(gray, cv::imdecode(bytes, cv::IMREAD_GRAYSCALE)), 1.0);
  cv::Mat ycrcb, channels[3], reference_cr;
  cv::cvtColor(cv::imdecode(bytes, cv::IMREAD_COLOR), ycrcb, cv::COLOR_BGR2YCrCb);
  cv::split(ycrcb, channels);
  cv::resize(channels[1], reference_cr, cr.size(), 0, 0, cv::INTER_AREA);
  EXPECT_LT(mean_abs_difference(cr, reference_cr), 2.0);

  const std::vector<std::uint8_t> garbage(4000, 0x5a);
  EXPECT_FALSE(decoder.decode(garbage, gray, cr));
  EXPECT_TRUE(gray.empty()) << "a frame that is not a JPEG leaves no picture behind";
  EXPECT_TRUE(cr.empty());
  ASSERT_TRUE(decoder.decode(bytes, gray, cr)) << "the decoder recovers on the next good frame";
  EXPECT_EQ(gray.size(), card.size());
}

TEST_F(MediaFilesTest, JpegPreviewsDecodeToTheImageAndShrinkWithQuality) {
  const cv::Mat card = test_card();
  JpegEncoder fine_encoder(90), coarse_encoder(20);
  const std::string fine = fine_encoder.encode(card), coarse = coarse_encoder.encode(card);
  const cv::Mat decoded = cv::imdecode(std::vector<uchar>(fine.begin(), fine.end()), cv::IMREAD_COLOR);
  ASSERT_EQ(decoded.size(), card.size());
  EXPECT_LT(mean_abs_difference(gray_of(decoded), gray_of(card)), 3.0);
  EXPECT_LT(coarse.size(), fine.size());
  JpegEncoder gray_encoder(80);
  const std::string gray = gray_encoder.encode(gray_of(card));
  EXPECT_EQ(cv::imdecode(std::vector<uchar>(gray.begin(), gray.end()), cv::IMREAD_GRAYSCALE).size(), card.size());
}

// The monitor's encoder is kept from one preview to the next: every image comes out as itself,
// through changes of content, size and kind.
TEST_F(MediaFilesTest, OneJpegEncoderFollowsItsImages) {
  const cv::Mat card = test_card();
  cv::Mat inverted, small;
  cv::bitwise_not(card, inverted);
  cv::resize(card, small, {card.cols / 2, card.rows / 2});
  JpegEncoder encoder(90);
  for (const cv::Mat& image : {card, inverted, small, gray_of(inverted), card}) {
    const std::string bytes = encoder.encode(image);
    const cv::Mat decoded = cv::imdecode(std::vector<uchar>(bytes.begin(), bytes.end()), cv::IMREAD_GRAYSCALE);
    ASSERT_EQ(decoded.size(), image.size());
    EXPECT_LT(mean_abs_difference(decoded, image.channels() == 1 ? image : gray_of(image)), 3.0);
  }
}

TEST_F(MediaFilesTest, PngFilesHoldTheImageExactly) {
  const cv::Mat card = test_card();
  const fs::path colour = dir_ / "colour.png", gray = dir_ / "gray.png";
  write_png(colour, card);
  write_png(gray, gray_of(card));
  cv::Mat back = cv::imread(colour.string(), cv::IMREAD_UNCHANGED), difference;
  ASSERT_EQ(back.type(), CV_8UC3);
  cv::absdiff(back, card, difference);
  EXPECT_EQ(cv::countNonZero(difference.reshape(1)), 0);
  EXPECT_EQ(mean_abs_difference(cv::imread(gray.string(), cv::IMREAD_UNCHANGED), gray_of(card)), 0.0);
  try {
    write_png(dir_ / "no" / "such" / "dir.png", card);
    ADD_FAILURE() << "wrote into a missing folder";
  } catch (const MediaError& e) {
    EXPECT_THAT(e.what(), HasSubstr("dir.png"));
  }
}

TEST_F(MediaFilesTest, AnImagesExifOrientationIsReadBesideItsPlanes) {
  const cv::Mat card = test_card();
  const fs::path plain = dir_ / "plain.jpg";
  ASSERT_TRUE(cv::imwrite(plain.string(), card));
  cv::Mat gray, cr;
  EXPECT_EQ(read_image(plain, gray, cr), DisplayOrientation{}) << "no tag: as stored";
  // EXIF 1-8: as stored, mirrored, 180, mirrored + 180, mirrored + 270, 90, mirrored + 90, 270.
  using enum Rotation;
  const std::array<DisplayOrientation, 9> expected{{{}, {}, {k0, true}, {k180, false}, {k180, true}, {k270, true},
                                                    {k90, false}, {k90, true}, {k270, false}}};
  for (int tag = 1; tag <= 8; ++tag) {
    const fs::path file = dir_ / fmt::format("exif{}.jpg", tag);
    test::write_jpeg_with_orientation(file, card, tag);
    const DisplayOrientation orientation = read_image(file, gray, cr);
    EXPECT_EQ(orientation, expected[static_cast<std::size_t>(tag)]) << "EXIF " << tag;
    ASSERT_EQ(gray.size(), card.size()) << "planes as coded";
    // OpenCV's imread applies the tag itself: the planes shown as read must be its picture.
    const cv::Mat opencv = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat ours = shown(gray, orientation);
    ASSERT_EQ(ours.size(), opencv.size()) << "EXIF " << tag;
    EXPECT_LT(mean_abs_difference(ours, opencv), 1.0) << "EXIF " << tag;
  }
}

TEST_F(MediaFilesTest, AVideosDisplayMatrixIsReadAsAClockwiseTurn) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  // The stream's rotate tag as a phone writes it; FFmpeg's own player shows the file turned by
  // its display matrix, and so must the planes as read be, once turned.
  for (const int tag : {0, 90, 180, 270}) {
    const fs::path file = dir_ / fmt::format("rotate{}.mov", tag), first = dir_ / fmt::format("rotate{}.pgm", tag);
    ASSERT_NO_FATAL_FAILURE(ffmpeg(fmt::format("-i {} -frames:v 3 -c copy -metadata:s:v:0 rotate={} {}",
                                               test::kClip.string(), tag, file.string())));
    ASSERT_NO_FATAL_FAILURE(ffmpeg(fmt::format("-i {} -frames:v 1 -pix_fmt gray {}", file.string(), first.string())));
    VideoFile video(file);
    cv::Mat gray, cr;
    ASSERT_TRUE(video.read(gray, cr));
    EXPECT_EQ(static_cast<int>(video.orientation().turn), (360 - tag) % 360) << "rotate=" << tag;
    EXPECT_FALSE(video.orientation().mirrored);
    const cv::Mat player = cv::imread(first.string(), cv::IMREAD_GRAYSCALE);
    const cv::Mat ours = shown(gray, video.orientation());
    ASSERT_EQ(ours.size(), player.size()) << "rotate=" << tag;
    EXPECT_LT(mean_abs_difference(ours, player), 2.0) << "rotate=" << tag;
  }
}

TEST_F(MediaFilesTest, PixelsThatAreNotSquareAreReadStretchedToTheirShownProportions) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  // The clip's first frame squeezed to 3/4 of its width and declared as 4:3 pixels (as an
  // anamorphic recording stores it), and squeezed to 3/4 of its height as 3:4 pixels: read in
  // square pixels, each is the original frame again, up to the squeeze's blur.
  const fs::path square = dir_ / "square.pgm";
  ASSERT_NO_FATAL_FAILURE(
      ffmpeg(fmt::format("-i {} -frames:v 1 -pix_fmt gray {}", test::kClip.string(), square.string())));
  const cv::Mat original = cv::imread(square.string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(original.empty());
  for (const char* squeeze : {"scale=iw*3/4:ih,setsar=4/3", "scale=iw:ih*3/4,setsar=3/4"}) {
    SCOPED_TRACE(squeeze);
    const fs::path file = dir_ / "anamorphic.mkv";
    ASSERT_NO_FATAL_FAILURE(
        ffmpeg(fmt::format("-i {} -frames:v 1 -vf {} -c:v ffv1 {}", test::kClip.string(), squeeze, file.string())));
    VideoFile video(file);
    cv::Mat gray, cr;
    ASSERT_TRUE(video.read(gray, cr));
    ASSERT_EQ(gray.size(), original.size());
    EXPECT_LT(mean_abs_difference(gray, original), 3.0);
    EXPECT_LE(cr.cols, gray.cols);
    EXPECT_LE(cr.rows, gray.rows);
  }
}

// A pixel aspect no camera uses (a PNG's pHYs of 2000:1, 1:40) is taken as square pixels, not
// a stretch to thousands of times the picture's size.
TEST_F(MediaFilesTest, APixelAspectNoCameraUsesIsTakenAsSquare) {
  for (const char* aspect : {"2000/1", "1/40"}) {
    SCOPED_TRACE(aspect);
    const fs::path file = dir_ / "odd_aspect.mkv";
    ASSERT_NO_FATAL_FAILURE(ffmpeg(fmt::format(
        "-f lavfi -i testsrc=size=160x120:rate=25 -frames:v 1 -vf setsar={} -c:v ffv1 {}", aspect, file.string())));
    VideoFile video(file);
    cv::Mat gray, cr;
    ASSERT_TRUE(video.read(gray, cr));
    EXPECT_EQ(gray.size(), cv::Size(160, 120));
  }
}

TEST_F(MediaFilesTest, AnInterlacedPictureIsReadFromItsFirstFieldAlone) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  // The clip's first frame in one field and its negative in the other (the face and a very
  // different picture half a frame period later), coded interlaced in both field orders: read,
  // each is the first frame again, up to the field's half height, not the two combed together.
  const fs::path first = dir_ / "first.mkv";
  ASSERT_NO_FATAL_FAILURE(ffmpeg(fmt::format("-i {} -frames:v 1 -c:v ffv1 {}", test::kClip.string(), first.string())));
  cv::Mat original, original_cr;
  ASSERT_TRUE(VideoFile(first).read(original, original_cr));
  const std::pair<const char*, int> orders[] = {{"interleave_top,setfield=tff", 1},
                                                {"interleave_bottom,setfield=bff", 0}};
  for (const auto& [interleave, top_first] : orders) {
    SCOPED_TRACE(interleave);
    const fs::path file = dir_ / "interlaced.mpg";
    ASSERT_NO_FATAL_FAILURE(
        ffmpeg(fmt::format("-i {} -filter_complex "
                           "\"[0:v]trim=end_frame=1,split[a][b];[b]negate[n];[a][n]concat=n=2,"
                           "tinterlace={}\" -c:v mpeg2video -flags +ildct+ilme -top {} -q:v 2 {}",
                           test::kClip.string(), interleave, top_first, file.string())));
    VideoFile video(file);
    cv::Mat gray, cr;
    ASSERT_TRUE(video.read(gray, cr));
    ASSERT_EQ(gray.size(), original.size());
    ASSERT_EQ(cr.size(), original_cr.size());
    EXPECT_LT(mean_abs_difference(gray, original), 4.0);  // the fields combed: 67
    EXPECT_LT(mean_abs_difference(cr, original_cr), 4.0);
  }
}

// libswscale's SIMD code writes whole blocks, past the end of a row narrower than one: a red
// picture a few pixels wide (an RGB PNG, a 4:2:0 JPEG) is read as itself, and nothing is written
// past its planes, not even into a buffer of its exact size that the caller hands in.
TEST_F(MediaFilesTest, APictureAFewPixelsWideIsReadWithoutWritingPastItsPlanes) {
  constexpr int kRows = 600;
  constexpr std::uint8_t kUntouched = 0xa5;
  for (const int width : {1, 2, 3, 5, 17}) {
    for (const char* format : {"rgb24", "yuvj420p"}) {
      SCOPED_TRACE(fmt::format("{} px wide, {}", width, format));
      const bool rgb = std::string(format) == "rgb24";
      const fs::path file = dir_ / fmt::format("red{}.{}", width, rgb ? "png" : "jpg");
      ASSERT_NO_FATAL_FAILURE(
          ffmpeg(fmt::format("-f lavfi -i color=red:s=64x{} -frames:v 1 -vf scale={}:{},setsar=1 "
                             "-pix_fmt {} {}",
                             kRows, width, kRows, format, file.string())));
      const std::size_t size = static_cast<std::size_t>(width) * kRows;
      std::vector<std::uint8_t> gray_buffer(size + 64, kUntouched), cr_buffer(size + 64, kUntouched);
      cv::Mat gray(kRows, width, CV_8UC1, gray_buffer.data()), cr(kRows, width, CV_8UC1, cr_buffer.data());
      read_image(file, gray, cr);
      EXPECT_EQ(std::count(gray_buffer.begin() + static_cast<std::ptrdiff_t>(size), gray_buffer.end(), kUntouched), 64);
      EXPECT_EQ(std::count(cr_buffer.begin() + static_cast<std::ptrdiff_t>(size), cr_buffer.end(), kUntouched), 64);
      ASSERT_EQ(gray.size(), cv::Size(width, kRows));
      double low = 0, high = 0;
      cv::minMaxLoc(gray, &low, &high);
      EXPECT_NEAR(low, 76, 2) << "BT.601 luma of red";
      EXPECT_NEAR(high, 76, 2);
      ASSERT_FALSE(cr.empty());
      EXPECT_NEAR(cv::mean(cr)[0], 255, 3) << "full-range Cr of red";
    }
  }
}

TEST_F(MediaFilesTest, FfmpegsMessagesReachTheLogAsWholeLinesNamedByTheirComponent) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  std::ostringstream log;
  const auto before = spdlog::default_logger();
  auto logger = std::make_shared<spdlog::logger>("test", std::make_shared<spdlog::sinks::ostream_sink_mt>(log));
  logger->set_pattern("%l: %v");
  spdlog::set_default_logger(logger);
  route_ffmpeg_log();
  // An empty .mp4 (MP4's demuxer finds no index), and an MPEG program stream cut short: its
  // demuxer writes "Packet corrupt (...)" and "." as two pieces of one line, for every packet.
  const fs::path empty = dir_ / "empty.mp4", whole = dir_ / "whole.mpg", cut = dir_ / "cut.mpg";
  std::ofstream{empty};
  EXPECT_THROW(VideoFile{empty}, MediaError);
  ASSERT_NO_FATAL_FAILURE(
      ffmpeg(fmt::format("-i {} -frames:v 20 -c:v mpeg1video -f mpeg {}", test::kClip.string(), whole.string())));
  fs::copy_file(whole, cut);
  fs::resize_file(cut, 5000);
  {
    VideoFile video(cut);
    cv::Mat gray, cr;
    while (video.read(gray, cr)) {
    }
  }
  spdlog::set_default_logger(before);

  EXPECT_THAT(log.str(), HasSubstr("warning: ffmpeg: mov,mp4,m4a,3gp,3g2,mj2: moov atom not found\n"));
  EXPECT_THAT(log.str(), HasSubstr("warning: ffmpeg: mpeg: Packet corrupt (stream = 0, dts = NOPTS).\n"));
  EXPECT_THAT(log.str(), ::testing::ContainsRegex("warning: ffmpeg: mpeg: Packet corrupt \\(stream = 0, dts = "
                                                  "NOPTS\\)\\. \\([0-9]+ more times\\)"));
  std::istringstream lines(log.str());
  for (std::string line; std::getline(lines, line);) {
    EXPECT_THAT(line, ::testing::StartsWith("warning: ffmpeg: "));
    EXPECT_THAT(line, ::testing::Not(::testing::HasSubstr(" @ 0x")));  // no addresses
    EXPECT_THAT(line, ::testing::Not(::testing::EndsWith(": .")));     // no piece of a line alone
  }
}

}  // namespace
}  // namespace lipdrive
