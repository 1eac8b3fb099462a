// The audio inputs: ALSA capture through a fake device behind its seam (no sound card on a
// build machine) and through alsa-lib itself (the "null" device, an unknown device), the
// audio track of a recording decoded with FFmpeg, and the simulated microphone that plays it
// in step with the simulated camera.
#include "command_run.hpp"
#include "drivers/alsa_capture.hpp"
#include "drivers/audio_file.hpp"
#include "drivers/clock.hpp"
#include "fixture_paths.hpp"
#include "serial_peers.hpp"
#include "sim/simulated_audio.hpp"
#include "sim/simulated_camera.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <cerrno>
#include <cmath>
#include <deque>
#include <fstream>
#include <thread>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

// ---- a fake ALSA device -----------------------------------------------------------------

/// A capture device on a timeline the test sets: each read() hands out the next period of a
/// ramp (sample n of channel c is n · 10 + c), with the driver's timestamp `stamp_ns` and
/// `available` samples waiting behind it. Scripted errors come first.
class FakePcm final : public AlsaPcm {
 public:
  struct State {
    int opens = 0, restarts = 0;
    std::deque<std::string> open_results;  // "" = success; empty queue = success
    std::deque<long> read_errors;          // returned by read() before any data
    std::deque<int> wait_results;          // returned by wait() before the default (1)
    int channels = 1;
    long next_sample = 0;
    long available = 0;
    std::int64_t stamp_ns = 0;  // 0: no timestamp
    bool is_open = false;
  };
  explicit FakePcm(State& state) : s_(state) {}

  std::string open(const AlsaCaptureOptions& options) override {
    ++s_.opens;
    s_.channels = options.channels;
    std::string result;
    if (!s_.open_results.empty()) {
      result = s_.open_results.front();
      s_.open_results.pop_front();
    }
    s_.is_open = result.empty();
    return result;
  }
  void close() override { s_.is_open = false; }
  int wait(int) override {
    if (s_.wait_results.empty()) return 1;
    const int result = s_.wait_results.front();
    s_.wait_results.pop_front();
    return result;
  }
  long read(std::int16_t* interleaved, long frames) override {
    EXPECT_TRUE(s_.is_open);
    if (!s_.read_errors.empty()) {
      const long error = s_.read_errors.front();
      s_.read_errors.pop_front();
      return error;
    }
    for (long i = 0; i < frames; ++i, ++s_.next_sample)
      for (int c = 0; c < s_.channels; ++c)
        interleaved[i * s_.channels + c] = static_cast<std::int16_t>((s_.next_sample * 10 + c) % 30000);
    return frames;
  }
  bool timestamp(long& available, std::int64_t& time_ns) override {
    if (s_.stamp_ns == 0) return false;
    available = s_.available;
    time_ns = s_.stamp_ns;
    return true;
  }
  int restart() override {
    ++s_.restarts;
    return 0;
  }

 private:
  State& s_;
};

AlsaCaptureOptions fake_options() {
  AlsaCaptureOptions options;
  options.device = "hw:7,0";
  options.sample_rate = 16000;
  options.period_frames = 160;
  options.reopen_first = 5ms;
  options.reopen_max = 20ms;
  return options;
}

TEST(AlsaCapture, BlocksAreStampedFromTheDriversTimestampNotTheWakeUp) {
  FakePcm::State state;
  state.stamp_ns = 5'000'000'000;
  state.available = 80;  // half a period captured after the block
  AlsaCapture capture(fake_options(), std::make_unique<FakePcm>(state));
  AudioBlock block;
  std::this_thread::sleep_for(30ms);  // a late reader: the stamp must not move
  ASSERT_EQ(capture.read(block, 100ms), AudioStatus::kBlock);
  EXPECT_EQ(block.frames, 160);
  EXPECT_EQ(block.sample_rate, 16000);
  // (80 + 160) samples at 16 kHz = 15 ms before the driver's stamp.
  EXPECT_EQ(block.capture_time_ns, 5'000'000'000 - 15'000'000);
  EXPECT_EQ(block.position, 0u);
  state.stamp_ns += 10'000'000;  // the driver's next position update, one period later
  ASSERT_EQ(capture.read(block, 100ms), AudioStatus::kBlock);
  EXPECT_EQ(block.capture_time_ns, 5'000'000'000 - 5'000'000);
  EXPECT_EQ(block.position, 160u);
  EXPECT_DOUBLE_EQ(block.media_time_s, 0.01);
  EXPECT_EQ(capture.counters().blocks, 2u);
}

TEST(AlsaCapture, DeliversTheConfiguredChannelScaledToPlusMinusOne) {
  FakePcm::State state;
  state.stamp_ns = 1'000'000'000;
  AlsaCaptureOptions options = fake_options();
  options.channels = 2;
  options.channel = 1;
  AlsaCapture capture(options, std::make_unique<FakePcm>(state));
  AudioBlock block;
  ASSERT_EQ(capture.read(block, 100ms), AudioStatus::kBlock);
  for (int i : {0, 1, 100, 159}) EXPECT_FLOAT_EQ(block.samples[static_cast<std::size_t>(i)], (i * 10 + 1) / 32768.0f);
}

TEST(AlsaCapture, OverrunIsCountedAndTheLostSamplesShowAsAJump) {
  FakePcm::State state;
  state.stamp_ns = 1'000'000'000;
  AlsaCapture capture(fake_options(), std::make_unique<FakePcm>(state));
  AudioBlock block;
  ASSERT_EQ(capture.read(block, 100ms), AudioStatus::kBlock);
  const std::int64_t first = block.capture_time_ns;
  state.read_errors.push_back(-EPIPE);
  EXPECT_EQ(capture.read(block, 100ms), AudioStatus::kTimeout);  // never fatal
  EXPECT_EQ(capture.counters().xruns, 1u);
  EXPECT_EQ(state.restarts, 1);
  // The stream restarts 100 ms after the first block's end: 1600 samples were lost.
  state.stamp_ns += 110'000'000;
  ASSERT_EQ(capture.read(block, 100ms), AudioStatus::kBlock);
  EXPECT_EQ(block.capture_time_ns, first + 110'000'000);
  EXPECT_EQ(block.position, 160u + 1600u);
  EXPECT_EQ(capture.counters().samples_lost, 1600u);
  // Suspend (ESTRPIPE) is handled the same way.
  state.read_errors.push_back(-ESTRPIPE);
  EXPECT_EQ(capture.read(block, 100ms), AudioStatus::kTimeout);
  EXPECT_EQ(capture.counters().xruns, 2u);
  EXPECT_EQ(state.restarts, 2);
}

TEST(AlsaCapture, ALostDeviceIsReopenedWithBackOffNeverBlockingPastTheTimeout) {
  FakePcm::State state;
  state.stamp_ns = 1'000'000'000;
  AlsaCapture capture(fake_options(), std::make_unique<FakePcm>(state));
  AudioBlock block;
  ASSERT_EQ(capture.read(block, 100ms), AudioStatus::kBlock);
  state.read_errors.push_back(-ENODEV);
  state.open_results = {"cannot open the capture device: No such device",
                        "cannot open the capture device: No such device", ""};
  EXPECT_EQ(capture.read(block, 100ms), AudioStatus::kDisconnected);
  EXPECT_FALSE(state.is_open) << "a lost device is released at once";
  EXPECT_EQ(capture.counters().disconnects, 1u);
  int disconnected = 0;
  AudioStatus status = AudioStatus::kDisconnected;
  const auto start = std::chrono::steady_clock::now();
  while (status != AudioStatus::kBlock && disconnected < 100) {
    const auto before = std::chrono::steady_clock::now();
    status = capture.read(block, 3ms);
    EXPECT_LT(std::chrono::steady_clock::now() - before, 25ms) << "read() waits for the back-off at most its timeout";
    if (status == AudioStatus::kDisconnected) {
      ++disconnected;
      if (state.opens == 2) {
        EXPECT_NE(capture.reopen_error().find("No such device"), std::string::npos);
      }
    }
  }
  ASSERT_EQ(status, AudioStatus::kBlock);
  EXPECT_EQ(state.opens, 4);  // the first, then two failures and the success
  // Back-off: 5 + 10 + 20 ms at least before the success.
  EXPECT_GE(std::chrono::steady_clock::now() - start, 30ms);
  EXPECT_EQ(capture.counters().reconnects, 1u);
  EXPECT_TRUE(capture.reopen_error().empty());
}

TEST(AlsaCapture, ADeviceAbsentAtStartIsAnErrorOrRetriedAsAsked) {
  FakePcm::State state;
  state.open_results = {"cannot open the capture device: No such file or directory"};
  try {
    AlsaCapture capture(fake_options(), std::make_unique<FakePcm>(state));
    ADD_FAILURE() << "no error";
  } catch (const AudioSourceError& e) {
    EXPECT_STREQ(e.what(), "alsa:hw:7,0: cannot open the capture device: No such file or directory");
  }
  state.open_results = {"cannot open the capture device: No such file or directory"};
  AlsaCaptureOptions later = fake_options();
  later.must_open = false;
  AlsaCapture capture(later, std::make_unique<FakePcm>(state));
  EXPECT_FALSE(capture.is_open());
  EXPECT_NE(capture.reopen_error().find("No such file"), std::string::npos);
  AudioBlock block;
  state.stamp_ns = 1'000'000'000;
  AudioStatus status = AudioStatus::kDisconnected;
  for (int i = 0; i < 50 && status != AudioStatus::kBlock; ++i) status = capture.read(block, 10ms);
  EXPECT_EQ(status, AudioStatus::kBlock) << "plugged in later, it delivers";
}

TEST(AlsaCapture, ChannelOutOfRangeIsRejected) {
  FakePcm::State state;
  AlsaCaptureOptions options = fake_options();
  options.channel = 2;
  options.channels = 2;
  EXPECT_THROW(AlsaCapture(options, std::make_unique<FakePcm>(state)), AudioSourceError);
}

// ---- through alsa-lib -------------------------------------------------------------------

TEST(AlsaLib, AnUnknownDeviceIsAnErrorNamingIt) {
  AlsaCaptureOptions options;
  options.device = "lipdrive_no_such_device";
  try {
    AlsaCapture capture(options);
    ADD_FAILURE() << "no error";
  } catch (const AudioSourceError& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("alsa:lipdrive_no_such_device: cannot open the capture device"), std::string::npos)
        << message;
  }
}

TEST(AlsaLib, TheNullDeviceDeliversBlocksStampedOnTheMonotonicClock) {
  AlsaCaptureOptions options;
  options.device = "null";  // alsa-lib's own: it captures silence, with timestamps
  AlsaCapture capture(options);
  AudioBlock block;
  const std::int64_t before = monotonic_ns();
  ASSERT_EQ(capture.read(block, 200ms), AudioStatus::kBlock);
  const std::int64_t after = monotonic_ns();
  EXPECT_EQ(block.frames, 160);
  EXPECT_EQ(block.sample_rate, 16000);
  EXPECT_LT(block.capture_time_ns, after);
  // Within a second of the read: a monotonic stamp, not a wall-clock or zero one.
  EXPECT_GT(block.capture_time_ns, before - 1'000'000'000);
  EXPECT_EQ(block.samples[0], 0.0f);
}

// ---- the audio track of a recording -----------------------------------------------------

/// A 2 s clip: black until `event_s`, then white; its audio silent until `event_s`, then a
/// 440 Hz tone at half scale on the left channel only (the right stays silent).
fs::path make_flash_clip(const fs::path& dir, double event_s = 0.6, const std::string& name = "flash.mpg") {
  const fs::path clip = dir / name;
  const auto run = test::run_command(fmt::format(
      "ffmpeg -v error -y -f lavfi -i color=c=black:s=64x48:r=25:d=2 -f lavfi -i "
      "\"aevalsrc='if(gte(t,{0}),0.5*sin(2*PI*440*t),0)|0':s=44100:d=2\" "
      "-vf \"geq=lum='if(gte(T,{0}),235,16)':cb=128:cr=128\" -c:v mpeg1video -q:v 2 -c:a mp2 -b:a 192k -f mpeg {1}",
      event_s, clip.string()));
  EXPECT_EQ(run.exit_code, 0) << run.output;
  return clip;
}

TEST(AudioFile, DecodesTheTrackResampledToMonoOnTheVideosTimeline) {
  const test::TempDir dir;
  const fs::path clip = make_flash_clip(dir.path());
  const DecodedAudio audio = decode_audio(clip, 16000);
  EXPECT_EQ(audio.sample_rate, 16000);
  EXPECT_NEAR(static_cast<double>(audio.samples.size()) / 16000, 2.0, 0.1);
  // MPEG program streams start the audio a little before the first video frame.
  EXPECT_LT(std::abs(audio.start_s), 0.05);
  // The tone starts at 0.6 s on the video's timeline; its mono level is the mean of the
  // channels (0.25 peak), and it is a 440 Hz tone.
  const auto at = [&](double t) { return static_cast<std::size_t>((t - audio.start_s) * 16000); };
  double quiet = 0, loud = 0;
  int crossings = 0;
  for (std::size_t i = at(0.1); i < at(0.5); ++i) quiet = std::max(quiet, double(std::abs(audio.samples[i])));
  for (std::size_t i = at(0.8); i < at(1.8); ++i) {
    loud = std::max(loud, double(std::abs(audio.samples[i])));
    crossings += (audio.samples[i - 1] < 0) != (audio.samples[i] < 0);
  }
  EXPECT_LT(quiet, 0.01);
  EXPECT_NEAR(loud, 0.25, 0.03);
  EXPECT_NEAR(crossings / 2.0, 440, 5);
  std::size_t onset = at(0.3);
  while (onset < audio.samples.size() && std::abs(audio.samples[onset]) < 0.05) ++onset;
  EXPECT_NEAR(static_cast<double>(onset) / 16000 + audio.start_s, 0.6, 0.01);
}

TEST(AudioFile, SoundTheRecorderDroppedIsAGapInTimeNotLost) {
  // 3 s of a track whose samples from 1.0 to 1.5 s are missing, timestamps kept (a recorder
  // that lost them), and a 440 Hz tone from 2.0 to 2.5 s: decoded, the gap is silence and the
  // tone is heard at its time, not half a second early.
  const test::TempDir dir;
  const fs::path clip = dir.path() / "gapped.mkv";
  ASSERT_EQ(test::run_command(fmt::format("ffmpeg -v error -y -f lavfi -i sine=f=440:d=3:r=48000 -af "
                                          "\"volume='between(t,2,2.5)':eval=frame,aselect='not(between(t,1,1.5))'\" "
                                          "-c:a pcm_s16le {}",
                                          clip.string()))
                .exit_code,
            0);
  const DecodedAudio audio = decode_audio(clip, 16000);
  EXPECT_NEAR(static_cast<double>(audio.samples.size()) / 16000, 3.0, 0.03);
  std::size_t onset = 0;
  while (onset < audio.samples.size() && std::abs(audio.samples[onset]) < 0.05) ++onset;
  EXPECT_NEAR(static_cast<double>(onset) / 16000 + audio.start_s, 2.0, 0.01);
}

/// Crossings of zero per second over [from, to) seconds of the decoded samples, halved: the
/// frequency of a tone.
double tone_hz(const DecodedAudio& audio, double from, double to) {
  int crossings = 0;
  const auto at = [&](double t) { return static_cast<std::size_t>((t - audio.start_s) * audio.sample_rate); };
  for (std::size_t i = at(from) + 1; i < at(to); ++i) crossings += (audio.samples[i - 1] < 0) != (audio.samples[i] < 0);
  return crossings / 2.0 / (to - from);
}

TEST(AudioFile, ATrackWhoseChannelsChangeOnTheWayIsFollowed) {
  // Two MP3 recordings joined end to end, a stereo 440 Hz tone then a mono 880 Hz one: the
  // decoder's frames change from two channels to one in mid-track.
  const test::TempDir dir;
  const auto mp3 = [&](const char* name, int hz, int channels) {
    const fs::path file = dir.path() / name;
    EXPECT_EQ(
        test::run_command(fmt::format("ffmpeg -v error -y -f lavfi -i sine=f={}:d=1:r=44100 -ac {} -c:a libmp3lame "
                                      "-id3v2_version 0 -write_xing 0 {}",
                                      hz, channels, file.string()))
            .exit_code,
        0);
    return file;
  };
  const fs::path stereo = mp3("stereo.mp3", 440, 2), mono = mp3("mono.mp3", 880, 1);
  const fs::path joined = dir.path() / "joined.mp3";
  ASSERT_EQ(test::run_command(fmt::format("cat {} {} > {}", stereo.string(), mono.string(), joined.string())).exit_code,
            0);
  const DecodedAudio audio = decode_audio(joined, 16000);
  EXPECT_NEAR(static_cast<double>(audio.samples.size()) / 16000, 2.0, 0.1);
  EXPECT_NEAR(tone_hz(audio, 0.2, 0.8), 440, 5);
  EXPECT_NEAR(tone_hz(audio, 1.3, 1.8), 880, 5) << "the mono half at its own pitch and time";
}

TEST(AudioFile, ADamagedPacketIsSkippedAndTheRestOfTheTrackKept) {
  // An MP3 stream with garbage in the middle of a frame (a damaged recording): decoded, the
  // track keeps its length and the tone after the damage is heard at its time.
  const test::TempDir dir;
  const fs::path clean = dir.path() / "clean.mp3";
  ASSERT_EQ(test::run_command(fmt::format("ffmpeg -v error -y -f lavfi -i sine=f=440:d=2:r=44100 -c:a libmp3lame "
                                          "-id3v2_version 0 -write_xing 0 {}",
                                          clean.string()))
                .exit_code,
            0);
  std::string bytes;
  {
    std::ifstream in(clean, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_GT(bytes.size(), 8000u);
  for (std::size_t i = bytes.size() / 2; i < bytes.size() / 2 + 600; ++i) bytes[i] = static_cast<char>(0xff - (i % 7));
  const fs::path damaged = dir.path() / "damaged.mp3";
  std::ofstream(damaged, std::ios::binary) << bytes;
  const DecodedAudio audio = decode_audio(damaged, 16000);
  EXPECT_GT(audio.damaged_packets, 0);
  EXPECT_NEAR(static_cast<double>(audio.samples.size()) / 16000, 2.0, 0.1);
  EXPECT_NEAR(tone_hz(audio, 1.5, 1.9), 440, 5);
}

TEST(AudioFile, AClipWithoutAudioOrAFileThatIsNoRecordingIsAnErrorNamingIt) {
  const test::TempDir dir;
  const fs::path silent = dir.path() / "video_only.avi";
  ASSERT_EQ(test::run_command(fmt::format("ffmpeg -v error -y -f lavfi -i color=c=gray:s=64x48:r=25:d=1 -c:v mjpeg {}",
                                          silent.string()))
                .exit_code,
            0);
  try {
    decode_audio(silent, 16000);
    ADD_FAILURE() << "no error";
  } catch (const AudioSourceError& e) {
    EXPECT_EQ(std::string(e.what()), silent.string() + ": no audio track (the clip is video-only)");
  }
  const fs::path garbage = dir.path() / "garbage.mpg";
  std::ofstream(garbage) << "not a recording at all";
  try {
    decode_audio(garbage, 16000);
    ADD_FAILURE() << "no error";
  } catch (const AudioSourceError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(garbage.string() + ": ", 0), 0u) << e.what();
  }
  EXPECT_THROW(decode_audio(dir.path() / "absent.mpg", 16000), AudioSourceError);
}

TEST(AudioFile, SoundBelow8kHzIsRefusedBeforeItIsDecodedAndSpeechRatesAreNot) {
  // A 400 KB WAV at 10 Hz is 20,000 s long: resampled to 16 kHz it took 2.3 GB (at 1 Hz, all
  // the memory there was); 20 samples at 1 Hz decoded as "0.00 s long".
  const test::TempDir dir;
  const auto write_wav = [&](int rate, std::int64_t samples) {
    const fs::path file = dir.path() / fmt::format("{}hz.wav", rate);
    WavWriter wav(file, rate);
    wav.write_silence(samples);
    wav.close();
    return file;
  };
  const std::pair<int, std::int64_t> too_low[] = {{10, 200'000}, {1, 20}, {7999, 7999}};
  for (const auto& [rate, samples] : too_low) {
    const fs::path wav = write_wav(rate, samples);
    try {
      decode_audio(wav, 16000);
      ADD_FAILURE() << rate << " Hz: no error";
    } catch (const AudioSourceError& e) {
      EXPECT_EQ(
          std::string(e.what()),
          fmt::format("{}: sound at {} Hz; at least 8000 Hz (the lowest speech is recorded at)", wav.string(), rate));
    }
  }
  for (const int rate : {8000, 16000, 44100, 48000}) {
    const DecodedAudio audio = decode_audio(write_wav(rate, rate / 2), 16000);
    EXPECT_EQ(audio.source_rate, rate);
    EXPECT_NEAR(static_cast<double>(audio.samples.size()), 8000, 2) << rate << " Hz";
  }
}

// ---- the simulated microphone -----------------------------------------------------------

TEST(SimulatedClipAudio, PlaysTheTrackInRealTimeStampedOnTheReplayTimeline) {
  const test::TempDir dir;
  const fs::path clip = make_flash_clip(dir.path());
  const DecodedAudio track = decode_audio(clip, 16000);
  ReplayClock clock;
  SimulatedClipAudio audio({.clip = clip, .sample_rate = 16000, .block_frames = 160}, &clock);
  AudioBlock block;
  std::int64_t first_ns = 0;
  for (int n = 0; n < 20; ++n) {
    ASSERT_EQ(audio.read(block, 1000ms), AudioStatus::kBlock);
    if (n == 0) first_ns = block.capture_time_ns;
    EXPECT_EQ(block.position, static_cast<std::uint64_t>(n * 160));
    EXPECT_EQ(block.capture_time_ns, clock.start_ns() + n * 10'000'000);
    // Returned once its last sample is due, not before.
    EXPECT_GE(monotonic_ns(), block.capture_time_ns + 10'000'000);
  }
  EXPECT_EQ(first_ns, clock.start_ns());
  // The content is the track's, placed on the timeline by its start.
  const auto index = static_cast<std::ptrdiff_t>(19 * 160 + 5) - std::llround(track.start_s * 16000);
  EXPECT_FLOAT_EQ(block.samples[5], track.samples[static_cast<std::size_t>(index)]);
}

TEST(SimulatedClipAudio, StaysInStepWithTheCameraAcrossACameraOutageAndLoops) {
  const test::TempDir dir;
  const fs::path clip = make_flash_clip(dir.path(), 0.6);
  ReplayClock clock;
  SimulatedCameraOptions video{.input = clip, .real_time = true, .loop = true};
  video.faults.disconnect_after = 5;  // 0.2 s in, away for 0.6 s: back after the flash
  video.faults.reconnect = 600ms;
  SimulatedCamera camera(video, &clock);
  ASSERT_NEAR(camera.duration_s(), 2.0, 0.05);
  SimulatedClipAudio audio({.clip = clip, .sample_rate = 16000, .block_frames = 160, .loop_s = camera.duration_s()},
                           &clock);

  // The camera on a thread of its own, as in the daemon: capture times of bright frames.
  std::vector<std::int64_t> bright, dark;
  std::thread grabber([&] {
    Frame frame;
    const std::int64_t end = clock.start_ns() + 3'000'000'000;
    while (monotonic_ns() < end) {
      if (camera.grab(frame, 50ms) != GrabStatus::kFrame) continue;
      (cv::mean(frame.gray)[0] > 128 ? bright : dark).push_back(frame.capture_time_ns);
    }
  });
  // Tone onsets on the audio timeline: the first loud sample of each pass.
  std::vector<std::int64_t> onsets;
  bool loud = false;
  AudioBlock block;
  while (monotonic_ns() < clock.start_ns() + 3'000'000'000) {
    if (audio.read(block, 50ms) != AudioStatus::kBlock) continue;
    for (int i = 0; i < block.frames; ++i) {
      const bool now_loud = std::abs(block.samples[static_cast<std::size_t>(i)]) > 0.05f;
      if (now_loud && !loud) onsets.push_back(block.capture_time_ns + i * 62'500);
      if (std::abs(block.samples[static_cast<std::size_t>(i)]) > 0.05f) loud = true;
    }
    // The tone has zero crossings: silence only counts after a whole quiet block.
    bool quiet_block = true;
    for (int i = 0; i < block.frames; ++i) quiet_block &= std::abs(block.samples[static_cast<std::size_t>(i)]) < 0.01f;
    if (quiet_block) loud = false;
  }
  grabber.join();
  ASSERT_FALSE(bright.empty());
  ASSERT_GE(onsets.size(), 2u) << "the tone starts in each pass of the looping replay";
  // The camera came back 0.8 s in, after the flash: its first bright frame is the one due
  // then, not the first bright frame of the recording (which it never showed).
  const std::int64_t start = clock.start_ns();
  EXPECT_NEAR(static_cast<double>(bright.front() - start) / 1e9, 0.8, 0.06);
  EXPECT_NEAR(static_cast<double>(onsets[0] - start) / 1e9, 0.6, 0.01);
  // Second pass: the flash and the tone at 2.6 s, together within a frame period.
  const auto second_flash = std::ranges::find_if(bright, [&](std::int64_t t) { return t > start + 2'300'000'000; });
  ASSERT_NE(second_flash, bright.end());
  EXPECT_NEAR(static_cast<double>(*second_flash - onsets[1]) / 1e6, 0.0, 45.0)
      << "flash and tone of the second pass, ms apart";
  EXPECT_NEAR(static_cast<double>(onsets[1] - start) / 1e9, 2.6, 0.01);
}

TEST(SimulatedClipAudio, AnInjectedDisconnectLosesItsSamplesThenDeliversAgain) {
  const test::TempDir dir;
  const fs::path clip = make_flash_clip(dir.path());
  SimulatedClipAudio audio(
      {.clip = clip, .sample_rate = 16000, .block_frames = 160, .disconnect_after_s = 0.1, .reconnect = 200ms});
  AudioBlock block;
  for (int n = 0; n < 10; ++n) ASSERT_EQ(audio.read(block, 1000ms), AudioStatus::kBlock);
  int disconnected = 0;
  AudioStatus status;
  while ((status = audio.read(block, 20ms)) == AudioStatus::kDisconnected) ++disconnected;
  ASSERT_EQ(status, AudioStatus::kBlock);
  EXPECT_GE(disconnected, 5);
  EXPECT_EQ(block.position, 16000u * 3 / 10) << "samples resume at 0.3 s on the timeline";
}

TEST(SimulatedClipAudio, AClipWithoutAudioIsAnErrorNamingIt) {
  LIPDRIVE_REQUIRE_BUILT(test::kClip);
  try {
    SimulatedClipAudio audio({.clip = test::kClip});
    ADD_FAILURE() << "no error";
  } catch (const AudioSourceError& e) {
    EXPECT_NE(std::string(e.what()).find(test::kClip.string() + ": no audio track"), std::string::npos) << e.what();
  }
}

TEST(SimulatedClipAudio, GridClipPlaysItsWholeTrack) {
  const fs::path clip = test::shared_fixtures() / "grid" / "bbaf2n.mpg";
  LIPDRIVE_SKIP_WITHOUT_SHARED(clip);
  const DecodedAudio audio = decode_audio(clip, 16000);
  EXPECT_NEAR(static_cast<double>(audio.samples.size()) / 16000, 2.95, 0.05);
  EXPECT_NEAR(audio.start_s, 0.0, 0.001);
  double peak = 0;
  for (float s : audio.samples) peak = std::max(peak, double(std::abs(s)));
  EXPECT_GT(peak, 0.05) << "speech, not silence";
}

}  // namespace
}  // namespace lipdrive
