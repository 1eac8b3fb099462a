// The daemon's pipeline: the lock-free hand-overs, the pipeline on the simulated camera
// (tracking, zero allocations per frame, a camera disconnect), and `lipdrive run` as a
// process (--frames/--stats, SIGTERM, SIGHUP).
//
// Allocations are counted by tests/allocation_counter.cpp on the processing thread alone.
#include "allocation_counter.hpp"
#include "build_paths.hpp"
#include "captured_log.hpp"
#include "daemon_process.hpp"
#include "drivers/cpu_latency.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/config/performer_profile.hpp"
#include "firmware_app/daemon/capture.hpp"
#include "firmware_app/daemon/latest_frame.hpp"
#include "firmware_app/daemon/pipeline.hpp"
#include "firmware_app/daemon/take_recorder.hpp"
#include "firmware_app/daemon/timecode_source.hpp"
#include "firmware_app/tables/measures_csv.hpp"
#include "fixture_paths.hpp"
#include "pipeline_parts.hpp"
#include "shared_predictor.hpp"
#include "sim/simulated_camera.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <new>
#include <optional>
#include <pthread.h>
#include <sched.h>
#include <sstream>
#include <stdexcept>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using ::testing::HasSubstr;

using test::AllocationWatch;
using test::kClip;
using test::kModel;
using test::make_processor;

// ---------------------------------------------------------------- hand-over structures

struct Numbered {
  std::uint64_t value = 0;
};

TEST(LatestFrame, WriterNeverWaitsAndReaderGetsTheNewest) {
  LatestFrame<Numbered> latest;
  EXPECT_EQ(latest.take(1ms), nullptr);
  // No reader at all: the writer still completes every publish.
  for (std::uint64_t i = 1; i <= 1000; ++i) {
    latest.back().value = i;
    latest.publish();
  }
  const Numbered* newest = latest.take(0ms);
  ASSERT_NE(newest, nullptr);
  EXPECT_EQ(newest->value, 1000u);
  EXPECT_EQ(latest.dropped(), 999u);
  EXPECT_EQ(latest.take(1ms), nullptr) << "a taken frame is not delivered twice";
}

TEST(LatestFrame, ConcurrentReaderSeesIncreasingFramesAndDropsAddUp) {
  LatestFrame<Numbered> latest;
  constexpr std::uint64_t kFrames = 200'000;
  std::atomic<bool> done{false};
  std::uint64_t taken = 0, last = 0;
  bool increasing = true;
  std::thread reader([&] {
    while (!done || last != kFrames) {
      if (const Numbered* frame = latest.take(10ms)) {
        increasing = increasing && frame->value > last;
        last = frame->value;
        ++taken;
        // Slower than the writer, so frames get replaced.
        const auto busy_until = std::chrono::steady_clock::now() + 2us;
        while (std::chrono::steady_clock::now() < busy_until) {
        }
      }
    }
  });
  for (std::uint64_t i = 1; i <= kFrames; ++i) {
    latest.back().value = i;
    latest.publish();
  }
  done = true;
  reader.join();
  EXPECT_TRUE(increasing);
  EXPECT_EQ(last, kFrames) << "the newest frame always reaches the reader";
  EXPECT_GT(latest.dropped(), 0u);
  EXPECT_EQ(taken + latest.dropped(), kFrames) << "every frame is either taken or counted as dropped";
}

TEST(LatestFrame, WaitingReaderWakesUpForANewFrame) {
  LatestFrame<Numbered> latest;
  std::thread writer([&] {
    std::this_thread::sleep_for(50ms);
    latest.back().value = 7;
    latest.publish();
  });
  const auto start = std::chrono::steady_clock::now();
  const Numbered* frame = latest.take(5s);
  const auto waited = std::chrono::steady_clock::now() - start;
  writer.join();
  ASSERT_NE(frame, nullptr);
  EXPECT_EQ(frame->value, 7u);
  EXPECT_LT(waited, 1s);
}

struct Triple {
  std::uint64_t a = 0, b = 0, c = 0;
};

TEST(Published, ReadersNeverSeeATornValue) {
  Published<Triple> published;
  Triple first;
  EXPECT_EQ(published.read(first), 0u);
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (std::uint64_t i = 1; i <= 200'000; ++i) published.publish({i, i * 2, i * 3});
    done = true;
  });
  bool consistent = true;
  std::uint32_t last_version = 0;
  bool monotonic = true;
  while (!done) {
    Triple t;
    const std::uint32_t version = published.read(t);
    consistent = consistent && t.b == 2 * t.a && t.c == 3 * t.a;
    monotonic = monotonic && version >= last_version;
    last_version = version;
  }
  writer.join();
  EXPECT_TRUE(consistent);
  EXPECT_TRUE(monotonic);
  Triple last;
  EXPECT_EQ(published.read(last), 200'000u);
  EXPECT_EQ(last.a, 200'000u);
}

TEST(LatencyHistogram, QuantilesOfKnownLatencies) {
  LatencyHistogram histogram;
  EXPECT_TRUE(std::isnan(histogram.quantile_ms(0.5)));
  for (int ms = 1; ms <= 100; ++ms) histogram.add(std::int64_t{ms} * 1'000'000 - 1000);  // just under each ms
  EXPECT_EQ(histogram.count(), 100u);
  EXPECT_NEAR(histogram.quantile_ms(0.5), 50.0, LatencyHistogram::kBinMs);
  EXPECT_NEAR(histogram.quantile_ms(0.99), 99.0, LatencyHistogram::kBinMs);
  histogram.add(std::int64_t{10'000} * 1'000'000);  // 10 s lands in the last bin
  EXPECT_EQ(histogram.quantile_ms(1.0), LatencyHistogram::kBins * LatencyHistogram::kBinMs);
}

// ---------------------------------------------------------------- the pipeline in-process

SimulatedCameraOptions clip_options() {
  SimulatedCameraOptions options;
  options.input = kClip;
  options.loop = true;
  return options;
}

/// Remembers what the outputs were given, from the output thread.
class RecordingOutput : public Output {
 public:
  void publish(const DriveFrame& frame) override {
    ++count;
    untracked += !(frame.status & kStatusTracking);
    opened = std::max(opened.load(), frame.values[0]);
    value = frame.values[0];
    status = frame.status;
    last = frame;
  }
  std::string describe() const override { return "test output"; }
  std::atomic<int> count{0}, untracked{0};
  std::atomic<double> opened{0};
  std::atomic<double> value{0};          // the first channel's, of the last frame
  std::atomic<std::uint16_t> status{0};  // the last frame's, for the test thread while the pipeline runs
  DriveFrame last;                       // read once the pipeline has stopped
};

void wait_for(const std::function<bool()>& condition, std::chrono::seconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!condition() && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(5ms);
}

class PipelineTest : public ::testing::Test {
 protected:
  void SetUp() override { LIPDRIVE_REQUIRE_BUILT(kClip); }
};

TEST_F(PipelineTest, TracksTheTalkingFaceAndOutputsEndNeutral) {
  PipelineSettings settings;
  settings.max_frames = 60;
  settings.channels = {
      ChannelSpec{.name = "open", .signal = Signal::kOpen, .out_min = 0, .out_max = 1000, .neutral = 100}};
  settings.safety.ease_ns = 100'000'000;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(clip_options()), make_processor(), settings, control);
  RecordingOutput output;
  pipeline.add_output(output);
  pipeline.start();
  wait_for([&] { return pipeline.finished(); }, 60s);
  FrameResult latest;
  ASSERT_GT(pipeline.latest(latest), 0u);
  EXPECT_TRUE(latest.tracked);
  EXPECT_GT(latest.width, 0);
  EXPECT_GE(latest.processed_time_ns, latest.capture_time_ns);
  EXPECT_GT(latest.measures.width_2d, 0);
  pipeline.stop();

  const PipelineStats stats = pipeline.stats();
  EXPECT_GE(stats.processed, 60u);
  EXPECT_GE(stats.captured, stats.processed);
  EXPECT_GT(static_cast<double>(stats.tracked), 0.9 * static_cast<double>(stats.processed));
  EXPECT_GT(stats.processed_p99_ms, 0);
  // Every stage of a frame lies inside its capture -> processed, so no quantile of a stage
  // exceeds the same quantile of the whole (a bin of rounding allowed).
  for (const PipelineStats::Stage& stage : {stats.hand_off, stats.landmarks, stats.fit, stats.measures}) {
    EXPECT_GT(stage.median_ms, 0);
    EXPECT_LE(stage.median_ms, stats.processed_median_ms + LatencyHistogram::kBinMs);
    EXPECT_LE(stage.p99_ms, stats.processed_p99_ms + LatencyHistogram::kBinMs);
  }
  EXPECT_GT(output.count, 0);
  EXPECT_GT(output.opened, 100) << "the open channel followed the talking mouth";
  EXPECT_FALSE(output.last.status & kStatusTracking) << "the last thing outputs see is the neutral pose";
  EXPECT_TRUE(output.last.status & kStatusFailSafe);
  ASSERT_EQ(output.last.channel_count, 1);
  EXPECT_EQ(output.last.values[0], 100);
}

/// Starts counting the processing thread's allocations once the tracker is warm. Paced as a
/// camera delivers (60 fps), so that the processing thread also waits and warms the caches
/// between frames.
TEST_F(PipelineTest, ProcessingAllocatesNothingPerFrame) {
  DriveControl control;
  SimulatedCameraOptions camera = clip_options();
  camera.real_time = true;
  camera.replay_rate = 60;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(camera), make_processor(), PipelineSettings{}, control);
  AllocationWatch watch;
  pipeline.add_sink(watch);
  const long before = test::allocation_count();
  pipeline.start();
  wait_for([&] { return watch.frames >= AllocationWatch::kWarmUp + 150; }, 120s);
  pipeline.stop();
  const PipelineStats stats = pipeline.stats();
  ASSERT_GE(watch.frames, AllocationWatch::kWarmUp + 150);
  // Re-detecting a lost face allocates (dlib's detector); the clip keeps the face tracked.
  ASSERT_EQ(stats.lost_track, 0u);
  // The default warm_ahead read the predictor's data before most frames, so the count covers it.
  EXPECT_GT(stats.warmed, stats.processed / 2);
  EXPECT_EQ(test::allocation_count() - before, 0) << "over " << watch.frames - AllocationWatch::kWarmUp << " frames";
}

/// The policy and name of each of this process's threads, from /proc/self/task.
std::map<std::string, int> thread_policies() {
  std::map<std::string, int> policies;
  for (const auto& task : fs::directory_iterator("/proc/self/task")) {
    std::ifstream comm(task.path() / "comm");
    std::string name;
    std::getline(comm, name);
    const int policy = sched_getscheduler(std::stoi(task.path().filename().string()));
    if (policy >= 0) policies[name] = policy;
  }
  return policies;
}

/// Whether this process may use SCHED_FIFO (root, CAP_SYS_NICE or RLIMIT_RTPRIO), tried on a
/// thread of its own.
bool realtime_allowed() {
  bool allowed = false;
  std::thread probe([&allowed] {
    sched_param param{};
    param.sched_priority = 1;
    allowed = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param) == 0;
  });
  probe.join();
  return allowed;
}

TEST_F(PipelineTest, FramePathThreadsAreNamedAndRealTimeWhenAskedAndAllowed) {
  PipelineSettings settings;
  settings.realtime_priority = 5;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(clip_options()), make_processor(), settings, control);
  pipeline.start();
  wait_for([&] { return pipeline.stats().processed >= 5; }, 60s);
  const std::map<std::string, int> policies = thread_policies();
  pipeline.stop();
  EXPECT_GE(pipeline.stats().processed, 5u) << "refused or granted, the frame path runs";
  const int expected = realtime_allowed() ? SCHED_FIFO : SCHED_OTHER;
  for (const char* name : {"lipdrive-captur", "lipdrive-proces", "lipdrive-output"}) {
    ASSERT_TRUE(policies.contains(name)) << name;
    EXPECT_EQ(policies.at(name), expected) << name;
  }
}

// [scheduling] cpu_latency_us: the kernel keeps the CPUs' wake-up latency at most the request
// while the frame path runs, and as it was once the pipeline has stopped.
TEST_F(PipelineTest, HoldsTheCpuLatencyRequestWhileTheFramePathRuns) {
  const std::optional<std::int32_t> before = CpuLatencyRequest::current_target();
  if (!before || ::access(CpuLatencyRequest::kDevice, W_OK) != 0)
    GTEST_SKIP() << CpuLatencyRequest::kDevice << " cannot be read and written here";
  PipelineSettings settings;
  settings.cpu_latency_us = 2;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(clip_options()), make_processor(), settings, control);
  pipeline.start();
  wait_for([&] { return pipeline.stats().processed >= 5; }, 60s);
  const std::optional<std::int32_t> running = CpuLatencyRequest::current_target();
  pipeline.stop();
  ASSERT_TRUE(running);
  EXPECT_LE(*running, 2);
  EXPECT_EQ(CpuLatencyRequest::current_target(), before);
}

/// The pipeline on the clip replayed in real time with `faults`, taking frames every 20 ms.
std::unique_ptr<Pipeline> replaying(const SimulatedCameraOptions::FaultInjection& faults, DriveControl& control) {
  SimulatedCameraOptions options = clip_options();
  options.real_time = true;
  options.faults = faults;
  PipelineSettings settings;
  settings.frame_wait = 20ms;
  return std::make_unique<Pipeline>(std::make_unique<SimulatedCamera>(options), make_processor(), settings, control);
}

/// An output whose publish() blocks once, for `block`, the first time it is called after arm():
/// a serial adapter that hangs the output thread in its open, a log that stopped being read.
class StuckOutput : public Output {
 public:
  explicit StuckOutput(std::chrono::milliseconds block) : block_(block) {}
  void publish(const DriveFrame&) override {
    if (!armed_.exchange(false)) return;
    stuck_at = std::chrono::steady_clock::now();
    std::this_thread::sleep_for(block_);
    freed_at = std::chrono::steady_clock::now();
  }
  std::string describe() const override { return "stuck output"; }
  void arm() { armed_ = true; }
  std::atomic<std::chrono::steady_clock::time_point> stuck_at{}, freed_at{};

 private:
  std::chrono::milliseconds block_;
  std::atomic<bool> armed_{false};
};

// A stuck output thread holds every output at its last values; the processing thread goes on,
// but the watchdog is not fed once the output thread has not come round for a second, so that
// systemd restarts the daemon; the pings resume when it comes round again.
TEST_F(PipelineTest, AStuckOutputThreadStopsTheWatchdogsPings) {
  const fs::path socket = fs::temp_directory_path() / fmt::format("lipdrive_notify_{}.sock", ::getpid());
  fs::remove(socket);
  test::NotifySocket notify(socket);
  ::setenv("NOTIFY_SOCKET", socket.c_str(), 1);
  SimulatedCameraOptions options = clip_options();
  options.real_time = true;
  PipelineSettings settings;
  settings.watchdog_interval = 50ms;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(options), make_processor(), settings, control);
  StuckOutput output(4000ms);
  pipeline.add_output(output);
  pipeline.start();
  using Clock = std::chrono::steady_clock;
  std::vector<Clock::time_point> pings;
  bool armed = false;
  const auto deadline = Clock::now() + 60s;
  while (Clock::now() < deadline) {
    if (notify.receive(50ms).find("WATCHDOG=1") != std::string::npos) pings.push_back(Clock::now());
    if (!pings.empty() && !std::exchange(armed, true)) output.arm();  // stuck once the watchdog is fed
    const Clock::time_point freed = output.freed_at;
    if (freed != Clock::time_point{} && !pings.empty() && pings.back() > freed) break;
  }
  pipeline.stop();
  ::unsetenv("NOTIFY_SOCKET");
  fs::remove(socket);
  const Clock::time_point stuck = output.stuck_at, freed = output.freed_at;
  ASSERT_NE(freed, Clock::time_point{}) << "the output was stuck and let go";
  const auto count_between = [&](Clock::time_point from, Clock::time_point to) {
    return std::count_if(pings.begin(), pings.end(), [&](Clock::time_point t) { return t > from && t < to; });
  };
  EXPECT_GT(count_between(Clock::time_point{}, stuck), 0) << "fed before";
  // The pings stop a second into it (read here a little later than sent).
  EXPECT_EQ(count_between(stuck + 2000ms, freed), 0) << "not fed while the output thread is stuck";
  EXPECT_GT(count_between(freed, Clock::time_point::max()), 0) << "fed again once it comes round";
}

TEST_F(PipelineTest, CameraDisconnectIsCountedAndFramesResume) {
  DriveControl control;
  const std::unique_ptr<Pipeline> replay = replaying({.disconnect_after = 10, .reconnect = 400ms}, control);
  Pipeline& pipeline = *replay;
  RecordingOutput output;
  pipeline.add_output(output);
  pipeline.start();
  wait_for([&] { return !pipeline.stats().connected; }, 30s);
  const PipelineStats during = pipeline.stats();
  EXPECT_EQ(during.disconnects, 1u);
  wait_for([&] { return pipeline.stats().captured >= during.captured + 10; }, 30s);
  pipeline.stop();
  const PipelineStats after = pipeline.stats();
  EXPECT_EQ(after.disconnects, 1u);
  EXPECT_TRUE(after.connected);
  EXPECT_GE(after.processed, during.processed + 5) << "frames are processed again after the reconnect";
  EXPECT_GT(output.untracked, 1) << "outputs heard that nothing was tracked while the camera was away";
}

/// Watches the drive through a camera outage: when tracking was last seen, when the channel
/// first sat at neutral afterwards, and whether it followed the face again once it was back.
class OutageWatch : public Output {
 public:
  /// An outage begins with the first drive frame `begins` holds for (by default: the camera away).
  explicit OutageWatch(
      double neutral, std::function<bool(const DriveFrame&)> begins =
                          [](const DriveFrame& frame) { return !(frame.status & kStatusCameraConnected); })
      : neutral_(neutral), begins_(std::move(begins)) {}
  void publish(const DriveFrame& frame) override {
    const bool tracked = frame.status & kStatusTracking;
    if (begins_(frame)) outage_seen = true;
    if (!outage_seen) {
      if (tracked) last_tracked_ns = frame.time_ns;
      return;
    }
    if (neutral_at_ns == 0 && frame.values[0] == neutral_) {
      neutral_at_ns = frame.time_ns;
      fail_safe_at_neutral = frame.status & kStatusFailSafe;
    }
    if (neutral_at_ns != 0 && tracked && frame.values[0] != neutral_) followed_again = true;
  }
  std::string describe() const override { return "outage watch"; }

  std::atomic<bool> outage_seen{false}, fail_safe_at_neutral{false}, followed_again{false};
  std::atomic<std::int64_t> last_tracked_ns{0}, neutral_at_ns{0};

 private:
  double neutral_;
  std::function<bool(const DriveFrame&)> begins_;
};

/// One channel, "open": the signal (0..1) maps to 0..500 and neutral sits at 1000, which only
/// the fail-safe reaches; hold 200 ms, ease 300 ms.
PipelineSettings neutral_out_of_reach() {
  PipelineSettings settings;
  settings.channels = {ChannelSpec{
      .name = "open", .signal = Signal::kOpen, .in_max = 2, .out_min = 0, .out_max = 1000, .neutral = 1000}};
  settings.safety = {.hold_ns = 200'000'000, .ease_ns = 300'000'000};
  return settings;
}

TEST_F(PipelineTest, ACameraThatFallsSilentWithoutAnErrorIsNotConnectedUntilFramesComeAgain) {
  // A stream that stalls without reporting anything (a cable glitch): grab() only times out.
  DriveControl control;
  const std::unique_ptr<Pipeline> replay = replaying({.stall_every = 20, .stall = 1500ms}, control);
  Pipeline& pipeline = *replay;
  pipeline.start();
  wait_for([&] { return !pipeline.stats().connected; }, 30s);
  ASSERT_FALSE(pipeline.stats().connected) << "reported after a second without frames";
  const PipelineStats during = pipeline.stats();
  EXPECT_EQ(during.disconnects, 0u) << "a silence is not a disconnect the source reported";
  wait_for([&] { return pipeline.stats().connected; }, 30s);
  EXPECT_TRUE(pipeline.stats().connected) << "connected again with the next frame";
  EXPECT_GT(pipeline.stats().captured, during.captured);
  pipeline.stop();
}

TEST_F(PipelineTest, CameraLossEasesTheDriveToNeutralAndBack) {
  SimulatedCameraOptions options = clip_options();
  options.real_time = true;
  options.faults.disconnect_after = 40;
  options.faults.reconnect = 1500ms;
  const PipelineSettings settings = neutral_out_of_reach();
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(options), make_processor(), settings, control);
  OutageWatch watch(1000);
  pipeline.add_output(watch);
  pipeline.start();
  wait_for([&] { return watch.followed_again.load(); }, 30s);
  pipeline.stop();
  ASSERT_TRUE(watch.outage_seen);
  ASSERT_GT(watch.neutral_at_ns, 0) << "the drive never reached neutral while the camera was away";
  const double to_neutral_ms = static_cast<double>(watch.neutral_at_ns - watch.last_tracked_ns) / 1e6;
  RecordProperty("loss_to_neutral_ms", std::to_string(to_neutral_ms));
  // hold + ease, within one output tick (20 ms) and one frame (40 ms) of the last tracked one.
  EXPECT_NEAR(to_neutral_ms, 500, 60);
  EXPECT_TRUE(watch.fail_safe_at_neutral);
  EXPECT_TRUE(watch.followed_again) << "the drive follows the face again after the reconnect";
}

/// A timecode source that throws while `failing` is set: a step of the frame before its result
/// is published, as dlib or OpenCV throw on a picture they cannot handle.
class FailingTimecode : public TimecodeSource {
 public:
  FailingTimecode() : TimecodeSource(TimecodeRate::k25) {}
  std::optional<std::int32_t> frame_at(std::int64_t) const override {
    if (!failing) return std::nullopt;
    ++thrown;
    throw std::runtime_error("test: this frame cannot be measured");
  }
  std::string describe() const override { return "failing timecode"; }
  std::atomic<bool> failing{false};
  mutable std::atomic<int> thrown{0};
};

// An exception on the processing thread does not end the daemon (std::terminate, the figure
// left where it was): the frame counts as untracked, the drive holds and eases to neutral while
// the errors go on, and follows the face again after them.
TEST_F(PipelineTest, FramesWhoseStepThrowsAreUntrackedAndTheDriveFollowsAgainAfterThem) {
  const testing::CapturedLog log;
  SimulatedCameraOptions options = clip_options();
  options.real_time = true;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(options), make_processor(), neutral_out_of_reach(), control);
  FailingTimecode timecode;
  pipeline.set_timecode(timecode);
  OutageWatch watch(1000, [&timecode](const DriveFrame&) { return timecode.thrown > 0; });
  pipeline.add_output(watch);
  pipeline.start();
  wait_for([&] { return watch.last_tracked_ns > 0; }, 30s);
  std::this_thread::sleep_for(1s);  // past the acquisition, whose frame reaches the drive late
  timecode.failing = true;
  wait_for([&] { return watch.neutral_at_ns > 0; }, 30s);
  std::this_thread::sleep_for(1s);  // errors on every frame for a second more
  timecode.failing = false;
  wait_for([&] { return watch.followed_again.load(); }, 30s);
  pipeline.stop();
  ASSERT_GT(watch.neutral_at_ns, 0) << "the drive never reached neutral while every frame threw";
  EXPECT_TRUE(watch.fail_safe_at_neutral);
  const double to_neutral_ms = static_cast<double>(watch.neutral_at_ns - watch.last_tracked_ns) / 1e6;
  EXPECT_NEAR(to_neutral_ms, 500, 60) << "hold + ease from the last tracked frame";
  EXPECT_TRUE(watch.followed_again) << "the drive follows the face again once frames are measured";
  EXPECT_GE(pipeline.stats().lost_track, 1u);
  const std::vector<std::string> errors = log.messages(spdlog::level::err);
  ASSERT_FALSE(errors.empty());
  EXPECT_THAT(errors.front(), HasSubstr("cannot be measured; the frame counts as untracked"));
  // At most ten lines a second, the rest counted: fewer lines than frames that threw.
  EXPECT_LT(static_cast<int>(errors.size()), timecode.thrown.load());
}

/// A camera the test plugs in and unplugs: while it is away, grab() says so after a while of
/// its timeout, as a camera waiting for its device does.
class PluggableCamera final : public FrameSource {
 public:
  explicit PluggableCamera(std::unique_ptr<FrameSource> camera) : camera_(std::move(camera)) {}
  GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) override {
    if (plugged_in) return camera_->grab(frame, timeout);
    std::this_thread::sleep_for(std::min(timeout, std::chrono::milliseconds(20)));
    ++away_grabs;
    return GrabStatus::kDisconnected;
  }
  double frame_rate() const override { return camera_->frame_rate(); }
  std::string describe() const override { return "pluggable camera"; }

  std::atomic<bool> plugged_in{false};
  std::atomic<int> away_grabs{0};

 private:
  std::unique_ptr<FrameSource> camera_;
};

// A camera not there at start (enumerated after the daemon started at boot) was never
// connected: only its loss after frames is a disconnect, counted and logged.
TEST_F(PipelineTest, ACameraAbsentAtStartIsNoDisconnectButItsUnplugAfterFramesIs) {
  SimulatedCameraOptions options = clip_options();
  options.real_time = true;
  auto pluggable = std::make_unique<PluggableCamera>(std::make_unique<SimulatedCamera>(options));
  PluggableCamera& camera = *pluggable;
  const testing::CapturedLog log;
  Capture capture(std::move(pluggable), "", "holding");
  capture.start("test-capture", 0);
  wait_for([&] { return camera.away_grabs >= 5; }, 10s);
  EXPECT_FALSE(capture.connected());
  EXPECT_EQ(capture.counters().disconnects, 0u) << "absent from the start";

  camera.plugged_in = true;
  wait_for([&] { return capture.counters().captured >= 5; }, 30s);
  EXPECT_TRUE(capture.delivering());
  EXPECT_EQ(capture.counters().disconnects, 0u);
  EXPECT_TRUE(log.messages(spdlog::level::warn).empty());

  camera.plugged_in = false;
  wait_for([&] { return !capture.connected(); }, 10s);
  capture.stop();
  EXPECT_EQ(capture.counters().disconnects, 1u) << "unplugged after frames";
  EXPECT_EQ(log.messages(spdlog::level::warn), std::vector<std::string>{"pluggable camera: disconnected; holding"});
}

/// A camera that was not there when the pipeline was built: it says the rate asked for, 60,
/// until its stream delivers, then the rate it runs at.
class LateCamera : public FrameSource {
 public:
  explicit LateCamera(std::unique_ptr<FrameSource> camera) : camera_(std::move(camera)) {}
  GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) override {
    const GrabStatus status = camera_->grab(frame, timeout);
    opened_ = opened_ || status == GrabStatus::kFrame;
    return status;
  }
  double frame_rate() const override { return opened_ ? camera_->frame_rate() : 60; }
  std::string describe() const override { return camera_->describe(); }

 private:
  std::unique_ptr<FrameSource> camera_;
  bool opened_ = false;
};

TEST_F(PipelineTest, ACameraThatOpensLateIsTrackedAtTheRateItRuns) {
  // It opens at 15 fps: a frame every 67 ms, more than three periods of the 60 fps asked for,
  // so a pipeline that kept the rate of its start would drop the tracking between frames.
  SimulatedCameraOptions options = clip_options();
  options.real_time = true;
  options.replay_rate = 15;
  PipelineSettings settings;
  settings.frame_wait = 20ms;
  DriveControl control;
  Pipeline pipeline(std::make_unique<LateCamera>(std::make_unique<SimulatedCamera>(options)), make_processor(),
                    settings, control);
  RecordingOutput output;
  pipeline.add_output(output);
  pipeline.start();
  wait_for([&] { return output.status & kStatusTracking; }, 30s);
  ASSERT_TRUE(output.status & kStatusTracking);
  const int untracked_before = output.untracked, count_before = output.count;
  wait_for([&] { return pipeline.stats().tracked >= 20; }, 30s);
  const int untracked = output.untracked - untracked_before, count = output.count - count_before;
  pipeline.stop();
  EXPECT_GT(count, 40) << "the output thread's ticks over 20 frames";
  EXPECT_EQ(untracked, 0) << "drive frames that lost the tracking between camera frames";
}

TEST_F(PipelineTest, AnOpenEnableSwitchEasesTheDriveToNeutralAndClosingItFollowsAgain) {
  SimulatedCameraOptions options = clip_options();
  options.real_time = true;
  const PipelineSettings settings = neutral_out_of_reach();
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(options), make_processor(), settings, control);
  RecordingOutput output;
  pipeline.add_output(output);
  pipeline.start();
  const auto following = [&] {
    const std::uint16_t status = output.status;
    return (status & kStatusTracking) && (status & kStatusOutputsEnabled) && !(status & kStatusFailSafe) &&
           output.value <= 500;
  };
  const auto at_neutral = [&] {
    const std::uint16_t status = output.status;
    return (status & kStatusTracking) && !(status & kStatusOutputsEnabled) && output.value == 1000;
  };
  wait_for(following, 30s);
  ASSERT_TRUE(following()) << "status " << output.status;

  control.enable_switch_closed.store(false);
  wait_for(at_neutral, 10s);
  EXPECT_TRUE(at_neutral()) << "status " << output.status << ", open " << output.value;
  EXPECT_TRUE(control.outputs_enabled) << "the output enable command is untouched";

  control.enable_switch_closed.store(true);
  wait_for(following, 10s);
  EXPECT_TRUE(following()) << "status " << output.status << ", open " << output.value;
  pipeline.stop();
}

TEST_F(PipelineTest, SideCameraMeasuresProtrusionAndTheFrontCarriesOnWithoutIt) {
  const fs::path side_clip = fs::path(test::kFixtureDir) / "side_view.avi";
  LIPDRIVE_REQUIRE_BUILT(side_clip);
  SimulatedCameraOptions front = clip_options();
  front.real_time = true;
  SimulatedCameraOptions side = front;
  side.input = side_clip;
  side.faults.disconnect_after = 100;  // 4 s in, the side camera goes away for 1.5 s
  side.faults.reconnect = 1500ms;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(front), make_processor(), PipelineSettings{}, control);
  // The reference is fixed on the side clip's first 10 frames: it starts at rest.
  pipeline.set_side_camera(
      std::make_unique<SideCamera>(std::make_unique<SimulatedCamera>(side), SideProfileSettings{}, 10));
  pipeline.start();
  int with_side = 0, front_alone = 0, side_back = 0;
  double most_protruded = 0;
  std::uint64_t seen = 0;
  const auto deadline = std::chrono::steady_clock::now() + 8s;
  while (std::chrono::steady_clock::now() < deadline) {
    FrameResult r;
    pipeline.latest(r);
    if (r.sequence != seen && r.tracked) {
      seen = r.sequence;
      if (r.side_used) {
        ++with_side;
        most_protruded = std::max(most_protruded, r.protrusion_side);
        side_back += front_alone > 10;
      } else if (with_side > 0) {
        ++front_alone;
      }
    }
    std::this_thread::sleep_for(5ms);
  }
  pipeline.stop();
  RecordProperty("frames_with_side", with_side);
  RecordProperty("frames_front_alone", front_alone);
  EXPECT_GT(with_side, 60) << "front and side frames paired";
  EXPECT_GT(most_protruded, 0.05) << "the rounded visemes of the side clip push the lips forward";
  EXPECT_GT(front_alone, 25) << "tracking went on while the side camera was away";
  EXPECT_GT(side_back, 5) << "the side camera was used again once it was back";
}

TEST_F(PipelineTest, ACalibrateRequestRecentresTheProfileOnTheProcessingThread) {
  PipelineSettings settings;
  settings.neutral_frames = 10;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(clip_options()), make_processor(), settings, control);
  // A profile from someone else's face: its rest is far from what the clip's mouth shows.
  PerformerProfile before;
  before.rest = {0.6, 2.2, 0.3};
  before.open = {0.6, 1.0};
  before.width = {2.0, 2.6};
  before.protrusion = {0.3, 0.5};
  pipeline.set_profile(before);
  RecordingOutput output;
  pipeline.add_output(output);
  pipeline.start();
  wait_for([&] { return pipeline.stats().tracked >= 5; }, 60s);
  PerformerProfile after;
  EXPECT_EQ(pipeline.recentred_profile(after), 0u) << "nothing re-centred before a request";
  EXPECT_FALSE(output.status & kStatusCalibrated);

  const std::uint64_t tracked_at_request = pipeline.stats().tracked;
  pipeline.control().calibrate_requests.fetch_add(1);
  wait_for([&] { return pipeline.recentred_profile(after) > 0; }, 60s);
  const std::uint64_t tracked_at_recentre = pipeline.stats().tracked;
  wait_for([&] { return (output.status & kStatusCalibrated) != 0; }, 5s);
  pipeline.stop();

  ASSERT_EQ(pipeline.recentred_profile(after), 1u) << "one request, one re-centred profile";
  // The frame in flight when the request lands (already counted as tracked) may be the first.
  EXPECT_GE(tracked_at_recentre, tracked_at_request + 10u - 1u) << "captured on the tracked frames after the request";
  // Re-centred on the clip, not on the foreign profile's 0.6 of d: wherever the request lands,
  // the median of 10 frames of the clip's `open` is at most 0.425 (204 windows of
  // `lipdrive process build/fixtures/talking_face.avi`; 7 of them above 0.4). Each range moved
  // with the rest point.
  EXPECT_LT(after.rest.open, 0.5);
  EXPECT_NEAR(after.open.min, after.rest.open, 1e-12);
  EXPECT_NEAR(after.open.max - after.open.min, 0.4, 1e-9);
  EXPECT_NEAR(after.width.max - after.width.min, 0.6, 1e-9);
  EXPECT_NEAR(after.width.min - before.width.min, after.rest.width - before.rest.width, 1e-9);
  EXPECT_TRUE(after.calibrated);
  EXPECT_TRUE(output.last.status & kStatusCalibrated) << "the status word reports the profile in use";
}

TEST_F(PipelineTest, FullDiskStopsTheTakeButNotThePipeline) {
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(clip_options()), make_processor(), PipelineSettings{}, control);
  TakeRecorder recorder("clip", 50ms);
  pipeline.set_recorder(recorder);
  RecordingOutput output;
  pipeline.add_output(output);
  // Every write to /dev/full fails with ENOSPC.
  recorder.start("/dev/full");
  pipeline.start();
  wait_for([&] { return recorder.error().has_value(); }, 30s);
  ASSERT_TRUE(recorder.error().has_value());
  EXPECT_THAT(*recorder.error(), HasSubstr("/dev/full: recording stopped: No space left on device"));
  EXPECT_FALSE(recorder.recording());
  const std::uint64_t processed = pipeline.stats().processed;
  const int published = output.count;
  wait_for([&] { return pipeline.stats().processed > processed + 10 && output.count > published + 10; }, 30s);
  EXPECT_GT(pipeline.stats().processed, processed + 10) << "the pipeline keeps processing";
  EXPECT_GT(output.count, published + 10) << "and the outputs keep getting results";
  pipeline.stop();
}

// A disk that fills in the middle of a batch of rows (here the process's file-size limit, which
// cuts a write short as a full disk does, then fails it): the take keeps whole rows only, each
// with the header's fields, instead of ending in the middle of one.
TEST_F(PipelineTest, ADiskThatFillsMidRowLeavesTheTakeWithWholeRows) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("lipdrive_full_take_{}", ::getpid());
  fs::create_directories(dir);
  const fs::path take = dir / "take.csv";
  rlimit before{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &before), 0);
  const auto previous_handler = std::signal(SIGXFSZ, SIG_IGN);
  rlimit limited = before;
  limited.rlim_cur = 20'011;  // a prime: no row boundary falls on it by design
  ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &limited), 0);
  {
    DriveControl control;
    Pipeline pipeline(std::make_unique<SimulatedCamera>(clip_options()), make_processor(), PipelineSettings{}, control);
    TakeRecorder recorder("clip", 50ms);
    pipeline.set_recorder(recorder);
    recorder.start(take);
    pipeline.start();
    wait_for([&] { return recorder.error().has_value(); }, 30s);
    pipeline.stop();
    ASSERT_TRUE(recorder.error().has_value());
    EXPECT_THAT(*recorder.error(),
                HasSubstr("recording stopped: File too large; the take ends with its last whole row"));
  }
  ::setrlimit(RLIMIT_FSIZE, &before);
  std::signal(SIGXFSZ, previous_handler);
  std::ifstream file(take);
  const std::string text((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  ASSERT_GT(text.size(), 1000u);
  EXPECT_LT(text.size(), 20'011u);
  EXPECT_EQ(text.back(), '\n') << "the take ends in the middle of a row";
  std::istringstream lines(text);
  std::string line;
  std::getline(lines, line);
  const auto fields = std::count(line.begin(), line.end(), ',');
  int rows = 0;
  while (std::getline(lines, line)) {
    EXPECT_EQ(std::count(line.begin(), line.end(), ','), fields) << "row " << rows;
    ++rows;
  }
  EXPECT_GT(rows, 3);
  fs::remove_all(dir);
}

// The take's folder deleted while it records (a clean-up of the takes folder): the take stops
// with an error instead of writing on into a file nobody can open.
TEST_F(PipelineTest, ATakeWhoseFileIsRemovedStopsWithAnError) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("lipdrive_removed_take_{}", ::getpid());
  fs::create_directories(dir);
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(clip_options()), make_processor(), PipelineSettings{}, control);
  TakeRecorder recorder("clip", 50ms);
  pipeline.set_recorder(recorder);
  recorder.start(dir / "takes" / "take.csv");
  pipeline.start();
  wait_for([&] { return fs::exists(dir / "takes" / "take.csv") && fs::file_size(dir / "takes" / "take.csv") > 0; },
           30s);
  ASSERT_TRUE(recorder.recording());
  fs::remove_all(dir);
  wait_for([&] { return recorder.error().has_value(); }, 30s);
  pipeline.stop();
  ASSERT_TRUE(recorder.error().has_value());
  EXPECT_THAT(*recorder.error(), HasSubstr("the file was removed"));
  EXPECT_FALSE(recorder.recording());
}

// ---------------------------------------------------------------- `lipdrive run`

class RunTest : public ::testing::Test {
 protected:
  void SetUp() override {
    LIPDRIVE_REQUIRE_BUILT(kClip);
    dir_ = fs::temp_directory_path() / fmt::format("lipdrive_test_run_{}_{}", ::getpid(),
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
    config_ = dir_ / "lipdrive.toml";
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  void write_config(const std::string& camera = "real_time = false", int print_interval_ms = 0,
                    const std::string& rest = "") const {
    std::ofstream(config_) << fmt::format(
        "[model]\nfile = \"{}\"\n[camera]\ninput = \"{}\"\n{}\n[status]\nprint_interval_ms = {}\n{}\n", kModel.string(),
        kClip.string(), camera, print_interval_ms, rest);
  }
  fs::path dir_, config_;
};

TEST_F(RunTest, FramesAndStats) {
  write_config();
  test::DaemonProcess daemon(config_, dir_ / "stderr.txt", "--frames 50 --stats");
  EXPECT_EQ(daemon.wait(120s), 0) << daemon.log();
  const std::string log = daemon.log();
  EXPECT_THAT(log, HasSubstr("capture->processed latency: median"));
  EXPECT_THAT(log, HasSubstr("capture->processed by stage (median / p99 ms, 0.05 ms bins): hand-off"));
  EXPECT_THAT(log, HasSubstr("fps:"));
  unsigned long processed = 0;
  const auto at = log.find("processed ");
  ASSERT_NE(at, std::string::npos) << log;
  processed = std::stoul(log.substr(at + 10));
  EXPECT_GE(processed, 50u);
}

TEST_F(RunTest, SigtermStopsWithinOneSecond) {
  write_config("real_time = true");
  test::DaemonProcess daemon(config_, dir_ / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
  std::this_thread::sleep_for(300ms);
  const auto start = std::chrono::steady_clock::now();
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(1000ms), 0) << daemon.log();
  EXPECT_LT(std::chrono::steady_clock::now() - start, 1s);
}

TEST_F(RunTest, SighupKeepsRunningOnABadFileAndAppliesAGoodOne) {
  write_config("real_time = true");
  test::DaemonProcess daemon(config_, dir_ / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();

  write_config("real_time = true\nfps = 500");
  daemon.signal(SIGHUP);
  ASSERT_TRUE(daemon.wait_for_log("reload failed")) << daemon.log();
  EXPECT_THAT(daemon.log(), HasSubstr("key camera.fps: must be between 1 and 240, got 500"));
  std::this_thread::sleep_for(200ms);
  EXPECT_TRUE(daemon.running());

  // Status lines appear only with the new file, so seeing one shows it was applied.
  write_config("real_time = true", 100);
  daemon.signal(SIGHUP);
  ASSERT_TRUE(daemon.wait_for_log("fps, latency median")) << daemon.log();
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(2000ms), 0) << daemon.log();
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> fields;
  std::size_t start = 0;
  for (std::size_t comma; (comma = line.find(',', start)) != std::string::npos; start = comma + 1)
    fields.push_back(line.substr(start, comma - start));
  fields.push_back(line.substr(start));
  return fields;
}

TEST_F(RunTest, RecordWritesCompleteLinesWithTheProcessColumns) {
  const fs::path takes = dir_ / "takes";
  write_config("real_time = false", 0,
               fmt::format("[recording]\ndir = \"{}\"\nflush_interval_ms = 20", takes.string()));
  test::DaemonProcess daemon(config_, dir_ / "stderr.txt", "--record --frames 50 --stats");
  ASSERT_EQ(daemon.wait(120s), 0) << daemon.log();
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(takes)) files.push_back(entry.path());
  ASSERT_EQ(files.size(), 1u);
  EXPECT_THAT(files[0].filename().string(), ::testing::MatchesRegex("take-[0-9]{8}-[0-9]{6}\\.csv"));

  std::ifstream in(files[0]);
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  ASSERT_FALSE(text.empty());
  EXPECT_EQ(text.back(), '\n') << "only complete lines";
  std::istringstream lines(text);
  std::string line;
  std::getline(lines, line);
  const std::vector<std::string> header = split(line);
  // The columns of `lipdrive process`, then the capture time.
  EXPECT_EQ(line, measures_csv_header(false) + ",drive,capture_time_ns");
  int rows = 0, tracked = 0;
  std::int64_t last_capture = 0;
  bool ordered = true;
  while (std::getline(lines, line)) {
    const std::vector<std::string> fields = split(line);
    ASSERT_EQ(fields.size(), header.size()) << line;
    tracked += fields[3] == "1";
    const std::int64_t capture = std::stoll(fields.back());
    ordered = ordered && capture > last_capture;
    last_capture = capture;
    ++rows;
  }
  EXPECT_GE(rows, 50);
  EXPECT_GT(tracked, rows * 9 / 10);
  EXPECT_TRUE(ordered) << "rows in capture order";
}

TEST_F(RunTest, Sigusr1RecalibratesTheNeutralAndSavesTheProfile) {
  PerformerProfile profile;
  profile.rest = {0.6, 2.2, 0.3};
  profile.open = {0.6, 1.0};
  save_profile(dir_ / "alex.toml", "alex", profile);
  write_config("real_time = true", 0,
               fmt::format("[performer]\nname = \"alex\"\nprofiles_dir = \"{}\"\nneutral_frames = 10", dir_.string()));
  test::DaemonProcess daemon(config_, dir_ / "stderr.txt");
  ASSERT_TRUE(daemon.wait_for_log("running:")) << daemon.log();
  daemon.signal(SIGUSR1);
  ASSERT_TRUE(daemon.wait_for_log("calibrated neutral")) << daemon.log();
  // The main thread saves the profile after the processing thread applied it.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  PerformerProfile saved = load_profile(dir_ / "alex.toml", "alex");
  while (saved.rest.open == 0.6 && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(50ms);
    saved = load_profile(dir_ / "alex.toml", "alex");
  }
  EXPECT_LT(saved.rest.open, 0.4) << daemon.log();
  EXPECT_NEAR(saved.open.max - saved.open.min, 0.4, 1e-6);
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(2000ms), 0) << daemon.log();
}

TEST_F(RunTest, TellsSystemdReadyStatusAndFeedsTheWatchdog) {
  write_config("real_time = true", 200);
  test::NotifySocket notify(dir_ / "notify.sock");
  test::DaemonProcess daemon(config_, dir_ / "stderr.txt", "", {notify.environment(), "WATCHDOG_USEC=400000"});

  int ready = 0, status = 0, watchdog = 0;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while ((ready == 0 || status < 2 || watchdog < 5) && std::chrono::steady_clock::now() < deadline) {
    const std::string text = notify.receive(100ms);
    ready += text.find("READY=1") != std::string::npos;
    status += text.find("STATUS=") != std::string::npos && text.find("fps") != std::string::npos;
    watchdog += text.find("WATCHDOG=1") != std::string::npos;
  }
  EXPECT_EQ(ready, 1);
  EXPECT_GE(status, 2) << "a status every print interval";
  EXPECT_GE(watchdog, 5) << "pings at a fraction of WATCHDOG_USEC";
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(2000ms), 0) << daemon.log();
}

}  // namespace
}  // namespace lipdrive
