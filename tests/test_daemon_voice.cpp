// `lipdrive run` handing the drive to the performer's voice while the camera is away
// (docs/voice.md, "Hand-over"), on the simulated camera replaying a GRID clip with its sound.
//
// The clip: GRID lgaf4n ("lay green at f four now") twice; in the second sentence a hand is held
// before the mouth from 3.4 to 4.2 s, from 4.6 s the lens is covered and from 5.0 s there is no
// sound at all. The camera disconnects for 1.5 s after frame 25 (1.0 s, in the middle of the
// first sentence; it ends at 1.84 s). Over the gap the `open` channel must follow the voice
// (Pearson r >= 0.6 against the video-tracked `open` of the same frames, tracked without the
// gap), the status word must say "voice", the mouth must rest in the silence after the
// sentence. Behind the hand the face is not measured (no take row tracked) and the voice
// drives; the video again from the first frame without it. Once neither face nor sound is there
// the drive must reach neutral within hold + ease as without a voice. The voice model is
// trained here on the first 40 clips of ../shared/fixtures/grid_train (ridge regression, the
// CLI's context), lgaf4n not among them.
#include "command_run.hpp"
#include "core/calibration.hpp"
#include "core/metrics.hpp"
#include "core/voice_training.hpp"
#include "daemon_process.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/status_word.hpp"
#include "firmware_app/tables/csv_table.hpp"
#include "firmware_app/voice/voice_corpus.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"
#include "shared_predictor.hpp"
#include "sim/face_faults.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include <algorithm>
#include <cmath>
#include <optional>
#include <regex>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr double kFps = 25;
constexpr int kDisconnectAfter = 25;  // frames: 1.0 s
constexpr int kOutageMs = 1500;
// lgaf4n.align: "now" ends and silence follows; the hand before the mouth ("lay green at f" again);
// the lens covered, then no sound.
constexpr double kSentenceEnd = 1.84, kHandFrom = 3.4, kHandTo = 4.2;
constexpr double kCoverFrom = 4.6, kSoundTo = 5.0, kClipEnd = 7.0;
constexpr int kHoldMs = 250, kEaseMs = 500, kCrossfadeMs = 150, kAudioTimeoutMs = 200;
constexpr double kNeutral = 500;  // the open channel's neutral, output units (0..1000)
// open r over the gap: the target (0.739 in 3 runs since the video's open takes the lip colour;
// 0.540 and 0.586 before: docs/voice.md).
constexpr double kTargetR = 0.6;

fs::path grid_clip() { return test::shared_fixtures() / "grid" / "lgaf4n.mpg"; }

/// The voice model of the first 40 grid_train clips (file-name order).
VoiceModel train_model(FrameProcessor& processor) {
  std::vector<fs::path> clips;
  for (const auto& entry : fs::directory_iterator(test::shared_fixtures() / "grid_train"))
    if (entry.path().extension() == ".mpg") clips.push_back(entry.path());
  std::ranges::sort(clips);
  clips.resize(std::min<std::size_t>(clips.size(), 40));
  std::vector<VoiceRecording> recordings;
  for (const fs::path& clip : clips) recordings.push_back(load_voice_recording(clip, 16000, processor));
  VoiceTrainingSettings settings;
  settings.hidden = 0;  // ridge regression: scores as the hidden layer does (docs/voice.md), in a fraction of the time
  return train_voice_model(recordings, settings);
}

/// lgaf4n twice and a black second after, a hand (hand_of) before the mouth from kHandFrom to
/// kHandTo, the lens covered from kCoverFrom, the sound cut at kSoundTo.
struct Clip {
  fs::path path;
  int once = 0;  // lgaf4n's frames
};

Clip make_clip(const fs::path& dir, FrameProcessor& processor) {
  std::vector<cv::Mat> once;
  std::vector<Landmarks2D> face;  // of each frame of `once`, tracked in order
  processor.forget(FaceTracker::Next::kVideo);
  cv::VideoCapture capture(grid_clip().string());
  for (cv::Mat bgr, gray; capture.read(bgr);) {
    cv::cvtColor(bgr, gray, cv::COLOR_BGR2GRAY);
    const FrameMeasurement& m = processor.process(gray, cv::Mat());
    EXPECT_TRUE(m.tracked) << "frame " << once.size();
    once.push_back(bgr.clone());
    face.push_back(m.landmarks);
  }
  const fs::path picture = dir / "picture.avi", clip = dir / "lgaf4n_twice.mpg";
  cv::VideoWriter video(picture.string(), cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), kFps,
                        once.front().size());
  for (int n = 0; n < static_cast<int>(kClipEnd * kFps); ++n) {
    const double t = n / kFps;
    const std::size_t f = static_cast<std::size_t>(n) % once.size();
    cv::Mat frame = once[f];
    if (t >= kHandFrom && t < kHandTo) frame = held_before(frame, before_the_mouth(face[f]), hand_of(frame, face[f]));
    if (t >= kCoverFrom) frame = cv::Mat::zeros(frame.size(), frame.type());
    video.write(frame);
  }
  video.release();
  const test::CommandRun run = test::run_command(
      fmt::format("ffmpeg -v error -y -i {0} -i {1} -i {1} -filter_complex \"[1:a][2:a]concat=n=2:v=0:a=1[a];"
                  "[a]atrim=0:{2}[aa]\" -map 0:v -map '[aa]' -c:v mpeg1video -q:v 2 -c:a mp2 -b:a 192k -f mpeg {3}",
                  picture.string(), grid_clip().string(), kSoundTo, clip.string()));
  EXPECT_EQ(run.exit_code, 0) << run.output;
  return {clip, static_cast<int>(once.size())};
}

/// A drive frame read off the serial line, on the monotonic clock.
struct Sample {
  double t_s;  // since the replay's start
  double open;
  DriveSource source;
};

double drive_units(double open_measure) { return 1000 * PerformerProfile{}.open.scale(open_measure); }

TEST(DaemonVoice, TheVoiceDrivesWhileTheCameraIsAwayThenTheFailSafe) {
  LIPDRIVE_SKIP_WITHOUT_SHARED(grid_clip());
  LIPDRIVE_SKIP_WITHOUT_SHARED(test::shared_fixtures() / "grid_train");
  LIPDRIVE_REQUIRE_BUILT(test::kModel);
  const test::TempDir dir;
  static const MorphableModel face_model = load_model_file(test::kModel);
  FrameProcessor processor(face_model, kDefaultLandmarkSet, FitSettings{}, test::shared_predictor());
  const VoiceModel voice = train_model(processor);
  const fs::path voice_file = dir.path() / "performer.lpv";
  save_voice_model_file(voice_file, voice);
  const Clip clip = make_clip(dir.path(), processor);
  // The video-tracked `open` of every frame, from a run without the gap.
  const VoiceRecording reference = load_voice_recording(clip.path, 16000, processor);

  const test::PtyPair line(dir.path() / "pty");
  test::PtyReader reader(line.b);
  const fs::path takes = dir.path() / "takes", config = dir.path() / "lipdrive.toml";
  std::ofstream(config) << fmt::format(
      "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\nreal_time = true\nloop = false\n"
      "[camera.faults]\ndisconnect_after = {}\nreconnect_ms = {}\n"
      "[safety]\nhold_ms = {}\nease_ms = {}\n"
      "[recording]\ndir = \"{}\"\nstart = true\nflush_interval_ms = 100\n[status]\nprint_interval_ms = 500\n"
      "[voice]\nenabled = true\nmodel = \"{}\"\ninput = \"sim\"\ncrossfade_ms = {}\naudio_timeout_ms = {}\n"
      "[[channels]]\nname = \"open\"\nsignal = \"open\"\nout_min = 0\nout_max = 1000\nneutral = {}\n"
      "[[outputs.serial]]\nmode = \"framed\"\ndevice = \"{}\"\n",
      test::kModel.string(), clip.path.string(), kDisconnectAfter, kOutageMs, kHoldMs, kEaseMs, takes.string(),
      voice_file.string(), kCrossfadeMs, kAudioTimeoutMs, kNeutral, line.a.string());
  test::DaemonProcess daemon(config, dir.path() / "daemon.txt", "--stats");
  while (daemon.running()) {
    reader.read_available();
    std::this_thread::sleep_for(20ms);
  }
  ASSERT_EQ(daemon.wait(1s), 0) << daemon.log();
  const test::FrameStream stream = test::decode_frames(reader.read_available());
  ASSERT_GT(stream.frames.size(), 100u) << daemon.log();

  // The replay's start on the monotonic clock: each take row's capture time less its place in
  // the clip (the earliest: a frame is captured once it is due).
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(takes))
    if (entry.path().extension() == ".csv") files.push_back(entry.path());
  ASSERT_EQ(files.size(), 1u) << daemon.log();
  EXPECT_TRUE(fs::exists(fs::path(files.front()).replace_extension(".wav"))) << "the take's sound beside it";
  const CsvTable take = read_csv_table(files.front());
  const std::vector<double> time_s = numeric_column(take, "time_s"), capture = numeric_column(take, "capture_time_ns"),
                            tracked = numeric_column(take, "tracked");
  double start_ns = INFINITY;
  for (std::size_t r = 0; r < time_s.size(); ++r) start_ns = std::min(start_ns, capture[r] - time_s[r] * 1e9);
  // The gap: the longest step between rows.
  double gap_begin = 0, gap_end = 0;
  for (std::size_t r = 1; r < time_s.size(); ++r)
    if (time_s[r] - time_s[r - 1] > gap_end - gap_begin) gap_begin = time_s[r - 1], gap_end = time_s[r];
  EXPECT_NEAR(gap_end - gap_begin, kOutageMs / 1000.0, 0.15) << "the camera's outage";
  const std::size_t drive_column =
      static_cast<std::size_t>(std::ranges::find(take.header, "drive") - take.header.begin());
  ASSERT_LT(drive_column, take.header.size());
  for (std::size_t r = 0; r < take.rows.size(); ++r)
    if (tracked[r] == 1) {
      EXPECT_EQ(take.rows[r][drive_column], "video") << "row " << r;
    }
  // Behind the hand no row is measured and the voice drives; the video again from the first
  // frame without it.
  const auto frame_of = [](double t) { return static_cast<int>(std::lround(t * kFps)); };
  const int hand_from = frame_of(kHandFrom), hand_to = frame_of(kHandTo);
  int hand_rows = 0, hand_tracked = 0;
  std::optional<std::size_t> after_hand;
  for (std::size_t r = 0; r < take.rows.size(); ++r) {
    const int n = frame_of(time_s[r]);
    if (n >= hand_from && n < hand_to) {
      ++hand_rows;
      hand_tracked += tracked[r] == 1;
      EXPECT_EQ(take.rows[r][drive_column], "voice") << "row " << r << ", frame " << n << ", behind the hand";
    } else if (n >= hand_to && !after_hand) {
      after_hand = r;
    }
  }
  EXPECT_EQ(hand_tracked, 0) << "frames measured behind the hand";
  // Rows enough to say what happened: the daemon drops frames when it falls behind, and while
  // the hand is held the detector runs on every frame (under the sanitizers, longer than one).
  EXPECT_GE(hand_rows, (hand_to - hand_from) / 2) << "the hand's frames in the take";
  ASSERT_TRUE(after_hand.has_value());
  EXPECT_EQ(tracked[*after_hand], 1) << "the first frame without the hand";

  // The serial frames' times (µs, 32 bits) on the monotonic clock, near the start.
  std::vector<Sample> samples;
  const auto start_us = static_cast<std::int64_t>(start_ns / 1000);
  for (const test::DecodedFrame& f : stream.frames) {
    std::int64_t us = (start_us & ~0xffff'ffffLL) | f.time_us;
    if (us < start_us - (1LL << 31)) us += 1LL << 32;
    if (us > start_us + (1LL << 31)) us -= 1LL << 32;
    samples.push_back(
        {(static_cast<double>(us) * 1000 - start_ns) / 1e9, static_cast<double>(f.values[0]), status_source(f.status)});
  }
  // The drive at the moment a frame's sound is predicted: the look-ahead and the analysis
  // window's half after it, and the 10 ms block the look-ahead ends in.
  const double lag_s = voice.delay_s() + 0.010;
  const auto drive_at = [&](double t) -> const Sample* {
    const auto found = std::ranges::find_if(samples, [&](const Sample& s) { return s.t_s >= t + lag_s; });
    return found == samples.end() ? nullptr : &*found;
  };

  // Over the gap, past the cross-fade: the voice drives and follows the video's `open`.
  std::vector<double> drive, video, drive_speech, video_speech;
  int voice_frames = 0, gap_frames = 0, resting = 0, silent_frames = 0;
  double rest_level = drive_units(voice.rest[0]), worst_rest = 0;
  for (std::size_t n = 0; n < reference.targets.size(); ++n) {
    const double t = static_cast<double>(n) / kFps;
    // From the end of the cross-fade to the drive frame before the camera's return.
    if (t < gap_begin + kCrossfadeMs / 1000.0 || t + lag_s >= gap_end) continue;
    const Sample* s = drive_at(t);
    ASSERT_NE(s, nullptr);
    ++gap_frames;
    voice_frames += s->source == DriveSource::kVoice;
    EXPECT_EQ(s->source, DriveSource::kVoice) << "at " << t << " s";
    if (!reference.targets[n].tracked) continue;
    drive.push_back(s->open);
    video.push_back(drive_units(reference.targets[n].values[0]));
    if (t < kSentenceEnd) drive_speech.push_back(drive.back()), video_speech.push_back(video.back());
    // The silence after the sentence, once the voice activity's hangover and the gate have passed.
    if (t >= kSentenceEnd + 0.15) {
      ++silent_frames;
      resting += std::abs(s->open - rest_level) <= 1;
      worst_rest = std::max(worst_rest, std::abs(s->open - rest_level));
    }
  }
  const double r = compare_series(video, drive).pearson_r,
               r_speech = compare_series(video_speech, drive_speech).pearson_r;

  // Behind the hand, past the cross-fade: the voice drives and follows the `open` the video
  // tracked on the same frames of the first sentence.
  std::vector<double> drive_hand, video_hand;
  int voice_hand = 0, hand_frames = 0;
  for (int n = hand_from; n < hand_to; ++n) {
    const double t = n / kFps;
    if (t < kHandFrom + kCrossfadeMs / 1000.0 || t + lag_s >= kHandTo) continue;
    const Sample* s = drive_at(t);
    ASSERT_NE(s, nullptr);
    ++hand_frames;
    voice_hand += s->source == DriveSource::kVoice;
    if (!reference.targets[n - clip.once].tracked) continue;
    drive_hand.push_back(s->open);
    video_hand.push_back(drive_units(reference.targets[n - clip.once].values[0]));
  }
  const double r_hand = compare_series(video_hand, drive_hand).pearson_r;

  // Neither face nor sound: from the last frame the voice drove, hold + ease to neutral.
  const auto last_voice = std::ranges::find_if(samples.rbegin(), samples.rend(),
                                               [](const Sample& s) { return s.source == DriveSource::kVoice; });
  ASSERT_NE(last_voice, samples.rend());
  double neutral_after = INFINITY;
  for (auto s = last_voice.base(); s != samples.end(); ++s)
    if (s->open == kNeutral && s->source == DriveSource::kFailSafe) {
      neutral_after = s->t_s - last_voice->t_s;
      break;
    }

  // --stats: the sound block -> serial line latency while the voice drove.
  const std::string log = daemon.log();
  std::smatch latency;
  std::regex_search(log, latency, std::regex(R"(while the voice drives: median ([0-9.]+) ms, p99 ([0-9.]+) ms)"));
  fmt::print(
      "gap {:.2f}-{:.2f} s: {}/{} drive frames voice; open r {:.3f} over {} tracked frames ({:.3f} over the {} of "
      "the sentence); silence: {}/{} frames at the rest level (worst {:.1f} units); neutral {:.3f} s after the last "
      "voice-driven frame (hold + ease {:.3f} s); sound block->output median {} ms, p99 {} ms (look-ahead {:.0f} ms, "
      "delay {:.0f} ms); behind the hand: {} rows, {} measured, {}/{} drive frames voice, open r {:.3f} over {} "
      "frames\n",
      gap_begin, gap_end, voice_frames, gap_frames, r, drive.size(), r_speech, drive_speech.size(), resting,
      silent_frames, worst_rest, neutral_after, (kHoldMs + kEaseMs) / 1000.0,
      latency.size() > 2 ? latency[1].str() : "?", latency.size() > 2 ? latency[2].str() : "?",
      1e3 * voice.context.lookahead * voice.features.hop / voice.features.sample_rate, voice.delay_s() * 1e3, hand_rows,
      hand_tracked, voice_hand, hand_frames, r_hand, drive_hand.size());
  RecordProperty("open_r_over_gap", fmt::format("{:.3f}", r));
  RecordProperty("open_r_behind_the_hand", fmt::format("{:.3f}", r_hand));
  RecordProperty("open_r_over_gap_speech", fmt::format("{:.3f}", r_speech));
  RecordProperty("neutral_after_s", fmt::format("{:.3f}", neutral_after));
  if (latency.size() > 2) RecordProperty("voice_latency_ms", latency[1].str() + " / p99 " + latency[2].str());

  EXPECT_EQ(voice_frames, gap_frames);
  EXPECT_EQ(voice_hand, hand_frames) << "the voice drives behind the hand";
  EXPECT_GE(hand_frames, 10);
  EXPECT_GE(drive.size(), 25u);
  EXPECT_GE(r, kTargetR) << "the voice follows the video over the gap";
  EXPECT_GE(silent_frames, 5);
  EXPECT_EQ(resting, silent_frames) << "the mouth rests in the silence";
  EXPECT_NE(rest_level, kNeutral);
  EXPECT_LE(neutral_after, (kHoldMs + kEaseMs) / 1000.0 + 0.05) << daemon.log();
}

}  // namespace
}  // namespace lipdrive
