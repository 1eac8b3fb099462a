// The monitor page (docs/monitor.md): the preview hand-off on the processing thread (rate,
// decimation, no allocation per frame, the fitted lips on the tracked ones), and `lipdrive run`
// with [monitor] over HTTP: the page, the state, the preview and the history; commands refused
// without the token and carried out with it; clients beyond the bound turned away; a taken port
// or a bad address logged while the daemon runs on; the state equal to the daemon's counters.
#include "allocation_counter.hpp"
#include "build_paths.hpp"
#include "command_run.hpp"
#include "core/face_tracker.hpp"
#include "daemon_process.hpp"
#include "firmware_app/config/config.hpp"
#include "firmware_app/config/factories.hpp"
#include "firmware_app/config/model_files.hpp"
#include "firmware_app/daemon/daemon.hpp"
#include "firmware_app/daemon/pipeline.hpp"
#include "firmware_app/daemon/preview_feed.hpp"
#include "fixture_paths.hpp"
#include "pipeline_parts.hpp"
#include "serial_peers.hpp"
#include "shared_predictor.hpp"
#include "sim/simulated_camera.hpp"
#include "webdriver.hpp"

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using ::testing::HasSubstr;
using json = nlohmann::json;

using test::kClip;
using test::kModel;

constexpr const char* kToken = "0123456789abcdef-monitor";
const fs::path kSideClip = fs::path(test::kFixtureDir) / "side_view.avi";  // the default head in profile

bool wait_for(const std::function<bool()>& condition, std::chrono::milliseconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(20ms);
  }
  return true;
}

// ---------------------------------------------------------------- the preview hand-off

Landmarks2D no_landmarks() { return Landmarks2D::Constant(std::nan("")); }

TEST(PreviewFeed, OffersAtItsRateByCaptureTime) {
  PreviewFeed feed(10, 640);
  const cv::Mat gray(480, 640, CV_8UC1, cv::Scalar(90));
  constexpr std::int64_t kStart = 5'000'000'000, kFramePeriod = 16'666'667;  // a 60 fps camera
  for (int i = 0; i < 120; ++i)
    feed.offer(gray, static_cast<std::uint64_t>(i), kStart + i * kFramePeriod, false, no_landmarks(), no_landmarks());
  EXPECT_EQ(feed.offered(), 20u) << "10 a second over 2 s of frames";
  // After a pause the next frame is offered at once, and the rate holds from there.
  const std::int64_t later = kStart + 10'000'000'000;
  feed.offer(gray, 1000, later, false, no_landmarks(), no_landmarks());
  feed.offer(gray, 1001, later + kFramePeriod, false, no_landmarks(), no_landmarks());
  EXPECT_EQ(feed.offered(), 21u);
  const PreviewFrame* newest = feed.take(0ms);
  ASSERT_NE(newest, nullptr);
  EXPECT_EQ(newest->sequence, 1000u) << "the newest preview wins";
  EXPECT_EQ(feed.take(0ms), nullptr);
}

TEST(PreviewFeed, DecimatesTheFrameToFitAndKeepsTheLandmarksInFramePixels) {
  PreviewFeed feed(30, 320);
  cv::Mat gray(480, 640, CV_8UC1);
  for (int y = 0; y < gray.rows; ++y)
    for (int x = 0; x < gray.cols; ++x) gray.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((x * 7 + y * 3) % 251);
  Landmarks2D landmarks = Landmarks2D::Constant(100), fitted = Landmarks2D::Constant(101);
  feed.offer(gray, 1, 1'000'000'000, true, landmarks, fitted);
  const PreviewFrame* preview = feed.take(0ms);
  ASSERT_NE(preview, nullptr);
  EXPECT_EQ(preview->decimation, 2);
  ASSERT_EQ(preview->image.size(), cv::Size(320, 240));
  for (int y = 0; y < 240; y += 37)
    for (int x = 0; x < 320; x += 29)
      ASSERT_EQ(preview->image.at<std::uint8_t>(y, x), gray.at<std::uint8_t>(2 * y, 2 * x)) << x << "," << y;
  EXPECT_TRUE(preview->tracked);
  EXPECT_EQ(preview->landmarks(0, 0), 100);
  EXPECT_EQ(preview->fitted(1, 67), 101);
}

TEST(PreviewFeed, CarriesTheSideCamerasFrameAndProfileWhenThereIsOne) {
  PreviewFeed feed(30, 320);
  const cv::Mat front(480, 640, CV_8UC1, cv::Scalar(90));
  cv::Mat side(240, 320, CV_8UC1);
  for (int y = 0; y < side.rows; ++y)
    for (int x = 0; x < side.cols; ++x) side.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((x * 5 + y) % 253);
  SideProfile profile;
  profile.status = SideStatus::kNoLip;
  profile.nose_tip = {200, 100};
  feed.offer(front, 1, 1'000'000'000, false, no_landmarks(), no_landmarks(),
             SideView{.gray = &side, .profile = profile, .connected = true});
  const PreviewFrame* preview = feed.take(0ms);
  ASSERT_NE(preview, nullptr);
  ASSERT_TRUE(preview->side);
  EXPECT_EQ(preview->side_decimation, 1) << "the side frame fits as it is";
  EXPECT_EQ(cv::norm(preview->side_image, side, cv::NORM_L1), 0);
  EXPECT_EQ(preview->side_profile.status, SideStatus::kNoLip);
  EXPECT_EQ(preview->side_profile.nose_tip, cv::Point2f(200, 100));
  EXPECT_TRUE(preview->side_connected);
  // Without a side frame, the next preview says so.
  feed.offer(front, 2, 2'000'000'000, false, no_landmarks(), no_landmarks());
  preview = feed.take(0ms);
  ASSERT_NE(preview, nullptr);
  EXPECT_FALSE(preview->side);
}

// A preview on every frame (1000 a second asked), copied (640) or decimated (320), with and
// without a side camera, while a reader takes them as the monitor's encoder does: nothing is
// allocated on the processing thread.
struct PreviewCase {
  int size;
  bool side;
};
void PrintTo(const PreviewCase& c, std::ostream* out) { *out << c.size << (c.side ? " with side camera" : ""); }

class PreviewOnTheFramePath : public ::testing::TestWithParam<PreviewCase> {};

TEST_P(PreviewOnTheFramePath, AllocatesNothingAndTheFittedLipsLieOnTheTrackedOnes) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  SimulatedCameraOptions options;
  options.input = kClip;
  options.loop = true;
  DriveControl control;
  Pipeline pipeline(std::make_unique<SimulatedCamera>(options), test::make_processor(), PipelineSettings{}, control);
  if (GetParam().side) {
    LIPDRIVE_REQUIRE_BUILT(kSideClip);
    SimulatedCameraOptions side = options;
    side.input = kSideClip;
    pipeline.set_side_camera(
        std::make_unique<SideCamera>(std::make_unique<SimulatedCamera>(side), SideProfileSettings{}, 10));
  }
  PreviewFeed feed(1000, GetParam().size);
  pipeline.set_preview(feed);
  test::AllocationWatch watch;
  pipeline.add_sink(watch);
  std::atomic<bool> stop{false};
  int taken = 0, tracked = 0, with_side = 0, side_profiles = 0;
  double worst_lip_gap_px = 0, worst_lip_gap = 0;
  std::thread reader([&] {
    while (!stop) {
      const PreviewFrame* preview = feed.take(20ms);
      if (!preview) continue;
      ++taken;
      if (preview->side) {
        ++with_side;
        side_profiles += preview->side_profile.ok();
        EXPECT_EQ(preview->side_image.cols, 640 / preview->side_decimation);
      }
      if (!preview->tracked) continue;
      ++tracked;
      // The fitted model's lip landmarks against the tracked ones (48-67): mean distance over
      // the distance between the outer eye corners.
      double sum = 0;
      for (int i = ibug::kMouthCornerRight; i < kNumLandmarks; ++i)
        sum += (preview->fitted.col(i) - preview->landmarks.col(i)).norm();
      const double gap = sum / (kNumLandmarks - ibug::kMouthCornerRight);
      worst_lip_gap_px = std::max(worst_lip_gap_px, gap);
      worst_lip_gap = std::max(worst_lip_gap, gap / interocular_distance(preview->landmarks));
      EXPECT_EQ(preview->image.cols, 640 / preview->decimation);
    }
  });
  const long before = test::allocation_count();
  pipeline.start();
  ASSERT_TRUE(wait_for([&] { return watch.frames >= test::AllocationWatch::kWarmUp + 150; }, 120s));
  pipeline.stop();
  stop = true;
  reader.join();
  ASSERT_EQ(pipeline.stats().lost_track, 0u) << "re-detection allocates; the clip keeps the face";
  EXPECT_EQ(test::allocation_count() - before, 0)
      << "over " << watch.frames - test::AllocationWatch::kWarmUp << " frames";
  EXPECT_GE(feed.offered(), 150u);
  EXPECT_GT(taken, 20);
  EXPECT_GT(tracked, 20);
  if (GetParam().side) {
    EXPECT_GT(with_side, taken / 2) << "the side camera's frame rides along";
    EXPECT_GT(side_profiles, with_side / 2) << "with its profile found";
  } else {
    EXPECT_EQ(with_side, 0);
  }
  // On the lips: the mouth is about half the eye-corner distance wide, the fitted contour stays
  // within a tenth of that of the tracked points (a wrong scale or offset would be far off).
  EXPECT_LT(worst_lip_gap, 0.05) << worst_lip_gap_px << " px";
  RecordProperty("worst_mean_lip_gap_px", fmt::format("{:.2f}", worst_lip_gap_px));
  RecordProperty("worst_mean_lip_gap_interocular", fmt::format("{:.4f}", worst_lip_gap));
  std::printf("worst mean lip gap %.2f px, %.4f of the eye-corner distance\n", worst_lip_gap_px, worst_lip_gap);
}

INSTANTIATE_TEST_SUITE_P(Sizes, PreviewOnTheFramePath,
                         ::testing::Values(PreviewCase{640, false}, PreviewCase{320, false}, PreviewCase{640, true}));

// ---------------------------------------------------------------- the daemon over HTTP

/// A daemon configuration replaying the clip at 60 fps with the monitor on `port`, and
/// `tables` after [monitor].
std::string monitor_config(const fs::path& dir, int port, const std::string& monitor_keys = "",
                           const std::string& tables = "") {
  return test::sim_camera_at_60_fps() +
         fmt::format("[status]\nprint_interval_ms = 0\n[recording]\ndir = \"{}\"\n", (dir / "takes").string()) +
         test::channels_toml({"open", "width"}) + "neutral = 500\n" +
         fmt::format("[monitor]\nenabled = true\nport = {}\n{}\n", port, monitor_keys) + tables;
}

/// `lipdrive run` with the monitor on a free port, in a folder of its own.
struct MonitoredDaemon {
  explicit MonitoredDaemon(const std::string& monitor_keys = "", const std::string& tables = "")
      : port(test::free_port()), process(written(dir.path(), port, monitor_keys, tables), dir.path() / "stderr.txt") {}
  /// "monitor: http://..." in the log: it listens.
  bool listening() { return process.wait_for_log(fmt::format("monitor: http://127.0.0.1:{}/", port)); }
  /// SIGTERM, and a clean exit.
  void stop() {
    process.signal(SIGTERM);
    EXPECT_EQ(process.wait(5s), 0) << process.log();
  }

  const test::TempDir dir;
  const int port;
  test::DaemonProcess process;

 private:
  static fs::path written(const fs::path& dir, int port, const std::string& monitor_keys, const std::string& tables) {
    std::ofstream(dir / "lipdrive.toml") << monitor_config(dir, port, monitor_keys, tables);
    return dir / "lipdrive.toml";
  }
};

httplib::Client client(int port) {
  httplib::Client c("127.0.0.1", port);
  c.set_connection_timeout(2, 0);
  c.set_read_timeout(5, 0);
  return c;
}

json get_json(httplib::Client& c, const std::string& path) {
  const httplib::Result response = c.Get(path.c_str());
  if (!response || response->status != 200) {
    ADD_FAILURE() << path << ": "
                  << (response ? std::to_string(response->status) : httplib::to_string(response.error()));
    return json::object();
  }
  EXPECT_EQ(response->get_header_value("Content-Type"), "application/json");
  return json::parse(response->body);
}

json state(httplib::Client& c) { return get_json(c, "/api/state"); }

/// The state after the monitor's cache (50 ms) has certainly expired.
json fresh_state(httplib::Client& c) {
  std::this_thread::sleep_for(60ms);
  return state(c);
}

int post(httplib::Client& c, const std::string& path, const std::string& token = "") {
  httplib::Headers headers;
  if (!token.empty()) headers.emplace("Authorization", "Bearer " + token);
  const httplib::Result response = c.Post(path.c_str(), headers, "", "text/plain");
  return response ? response->status : -1;
}

TEST(MonitorHttp, ServesThePageTheStateThePreviewAndTheHistoryOnLoopback) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  MonitoredDaemon daemon;
  ASSERT_TRUE(daemon.listening()) << daemon.process.log();
  auto c = client(daemon.port);

  // Loopback by default: the listening socket is 127.0.0.1's alone.
  std::ifstream tcp("/proc/net/tcp");
  const std::string table{std::istreambuf_iterator<char>(tcp), std::istreambuf_iterator<char>()};
  EXPECT_THAT(table, HasSubstr(fmt::format(" 0100007F:{:04X} 00000000:0000 0A ", daemon.port))) << table;

  const httplib::Result page = c.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_THAT(page->get_header_value("Content-Type"), HasSubstr("text/html"));
  EXPECT_THAT(page->body, HasSubstr("<title>lipdrive monitor</title>"));
  EXPECT_THAT(page->body, HasSubstr("/api/state"));
  // Answers go out as they are, not compressed per request for a client that would accept it.
  for (const char* path : {"/", "/api/state", "/api/history"}) {
    const httplib::Result r = c.Get(path, {{"Accept-Encoding", "br, gzip, deflate"}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200);
    EXPECT_FALSE(r->has_header("Content-Encoding")) << path << ": " << r->get_header_value("Content-Encoding");
  }

  ASSERT_TRUE(wait_for([&] { return state(c)["frames"]["tracked"].get<int>() > 30; }, 60s)) << daemon.process.log();
  const json first = fresh_state(c);
  std::this_thread::sleep_for(500ms);
  const json second = fresh_state(c);
  EXPECT_GT(second["frames"]["processed"].get<int>(), first["frames"]["processed"].get<int>() + 10);
  EXPECT_GT(second["fps"].get<double>(), 30);
  EXPECT_TRUE(second["status"]["tracking"].get<bool>());
  ASSERT_EQ(second["channels"].size(), 2u);
  EXPECT_EQ(second["channels"][1]["name"], "width");
  EXPECT_EQ(second["channels"][1]["neutral"].get<double>(), 500);
  ASSERT_EQ(second["outputs"].size(), 0u);
  EXPECT_THAT(second["camera"].get<std::string>(), HasSubstr("talking_face.avi"));
  EXPECT_TRUE(second["side_camera"].is_null());
  EXPECT_EQ(second["monitor"]["previews"], 0) << "nobody asked for a preview: none is drawn or encoded";
  EXPECT_EQ(c.Get("/preview-side.jpg")->status, 404) << "no side camera, no side image";

  // The preview: a JPEG of the frame with its overlay, newer on every fetch.
  ASSERT_TRUE(wait_for(
      [&] {
        const httplib::Result r = c.Get("/preview.jpg");
        return r && r->status == 200;
      },
      10s));
  const httplib::Result preview = c.Get("/preview.jpg");
  ASSERT_TRUE(preview && preview->status == 200);
  EXPECT_EQ(preview->get_header_value("Content-Type"), "image/jpeg");
  const cv::Mat image =
      cv::imdecode(std::vector<unsigned char>(preview->body.begin(), preview->body.end()), cv::IMREAD_COLOR);
  ASSERT_EQ(image.size(), cv::Size(640, 480));
  std::this_thread::sleep_for(300ms);
  const httplib::Result later = c.Get("/preview.jpg");
  ASSERT_TRUE(later && later->status == 200);
  EXPECT_GT(std::stoull(later->get_header_value("X-Frame-Sequence")),
            std::stoull(preview->get_header_value("X-Frame-Sequence")));
  const cv::Mat later_image =
      cv::imdecode(std::vector<unsigned char>(later->body.begin(), later->body.end()), cv::IMREAD_COLOR);
  EXPECT_GT(cv::norm(image, later_image, cv::NORM_L1), 0);
  // The overlay's colours: magenta lips and green landmarks on a grey frame.
  int magenta = 0, green = 0;
  for (auto it = image.begin<cv::Vec3b>(); it != image.end<cv::Vec3b>(); ++it) {
    const cv::Vec3b p = *it;  // B, G, R
    magenta += p[0] > 160 && p[2] > 160 && p[1] < 110;
    green += p[1] > 160 && p[0] < 110 && p[2] < 110;
  }
  EXPECT_GT(magenta, 50);
  EXPECT_GT(green, 68);
  // Once nobody asks for previews (2 s), the encoder rests.
  std::this_thread::sleep_for(3s);
  const json resting = fresh_state(c);
  EXPECT_GT(resting["monitor"]["previews"].get<int>(), 0);
  std::this_thread::sleep_for(1s);
  EXPECT_EQ(fresh_state(c)["monitor"]["previews"], resting["monitor"]["previews"]);

  // The history: 25 samples a second per channel, and "since" returns only newer ones.
  const json history = get_json(c, "/api/history");
  const std::uint64_t next = history["next"];
  ASSERT_GT(next, 10u);
  ASSERT_EQ(history["values"].size(), 2u);
  EXPECT_EQ(history["values"][0].size(), history["time_s"].size());
  EXPECT_EQ(history["tracking"].size(), history["time_s"].size());
  EXPECT_EQ(history["period_ms"], 40);
  const auto [low, high] = std::minmax_element(history["values"][0].begin(), history["values"][0].end());
  EXPECT_GT(high->get<double>() - low->get<double>(), 10) << "the open channel moves";
  std::this_thread::sleep_for(200ms);
  const json newer = get_json(c, fmt::format("/api/history?since={}", next));
  EXPECT_GE(newer["time_s"].size(), 2u);
  EXPECT_LE(newer["time_s"].size(), newer["next"].get<std::uint64_t>() - next);
  EXPECT_GT(newer["time_s"][0].get<double>(), history["time_s"].back().get<double>());
  EXPECT_EQ(c.Get("/api/history?since=x")->status, 400);
  EXPECT_EQ(c.Get("/nothing-here")->status, 404);

  daemon.stop();
}

/// Pixels of `image` (BGR) near `colour`.
int pixels_of(const cv::Mat& image, const cv::Vec3b& colour) {
  int n = 0;
  for (auto it = image.begin<cv::Vec3b>(); it != image.end<cv::Vec3b>(); ++it)
    n += std::abs((*it)[0] - colour[0]) < 50 && std::abs((*it)[1] - colour[1]) < 50 &&
         std::abs((*it)[2] - colour[2]) < 50;
  return n;
}

/// A simulated side camera replaying the side-view clip (the default head in profile) at 60 fps.
std::string side_camera_table() {
  return fmt::format("[side_camera]\nenabled = true\ninput = \"{}\"\nreplay_fps = 60\n", kSideClip.string());
}

const cv::Vec3b kYellow{0, 220, 255}, kMagenta{255, 0, 255};  // the overlay's colours (BGR)

TEST(MonitorHttp, ShowsTheSideCamerasImageWithItsProfile) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  LIPDRIVE_REQUIRE_BUILT(kSideClip);
  MonitoredDaemon daemon("", side_camera_table());
  ASSERT_TRUE(daemon.listening()) << daemon.process.log();
  auto c = client(daemon.port);
  ASSERT_TRUE(wait_for([&] { return state(c)["frames"]["tracked"].get<int>() > 30; }, 60s)) << daemon.process.log();
  const json s = fresh_state(c);
  ASSERT_TRUE(s["side_camera"].is_object()) << s.dump();
  EXPECT_THAT(s["side_camera"]["camera"].get<std::string>(), HasSubstr("side_view.avi"));
  EXPECT_TRUE(s["side_camera"]["connected"].get<bool>());

  // The side image, newer on every fetch, with the profile drawn on it: the nose in yellow, the
  // upper lip in magenta (the clip's profile is found on nearly every frame).
  const fs::path artifacts = fs::path(test::kBuildDir) / "test_artifacts" / "monitor";
  fs::create_directories(artifacts);
  std::uint64_t last_sequence = 0;
  int newer = 0, with_profile = 0;
  for (int i = 0; i < 5; ++i) {
    const httplib::Result r = c.Get("/preview-side.jpg");
    ASSERT_TRUE(r);
    ASSERT_EQ(r->status, 200) << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "image/jpeg");
    const std::uint64_t sequence = std::stoull(r->get_header_value("X-Frame-Sequence"));
    newer += sequence > last_sequence;
    last_sequence = sequence;
    const cv::Mat image = cv::imdecode(std::vector<unsigned char>(r->body.begin(), r->body.end()), cv::IMREAD_COLOR);
    ASSERT_EQ(image.size(), cv::Size(640, 480));
    const int yellow = pixels_of(image, kYellow), magenta = pixels_of(image, kMagenta);
    with_profile += yellow > 20 && magenta > 10;
    if (i == 0) std::ofstream(artifacts / "side.jpg", std::ios::binary) << r->body;
    std::this_thread::sleep_for(300ms);
  }
  EXPECT_EQ(newer, 5);
  EXPECT_GE(with_profile, 3);
  daemon.stop();
}

/// Sends `request` as it is on a connection of its own (a write after the server closed is no
/// SIGPIPE) and returns what comes back within 2 s.
std::string raw_exchange(int port, std::string_view request) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  std::string response;
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) == 0 &&
      ::send(fd, request.data(), request.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(request.size())) {
    const auto deadline = std::chrono::steady_clock::now() + 2s;
    char buffer[1024];
    pollfd readable{fd, POLLIN, 0};
    while (std::chrono::steady_clock::now() < deadline && ::poll(&readable, 1, 100) >= 0) {
      if (!(readable.revents & (POLLIN | POLLHUP))) continue;
      const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
      if (n <= 0) break;
      response.append(buffer, static_cast<std::size_t>(n));
    }
  }
  ::close(fd);
  return response;
}

TEST(MonitorHttp, CommandsAreRefusedWithoutTheTokenAndCarriedOutWithIt) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  MonitoredDaemon daemon(fmt::format("token = \"{}\"", kToken));
  ASSERT_TRUE(daemon.listening()) << daemon.process.log();
  EXPECT_THAT(daemon.process.log(), ::testing::Not(HasSubstr(kToken))) << "a configured token is not logged";
  auto c = client(daemon.port);
  ASSERT_TRUE(wait_for([&] { return state(c)["frames"]["tracked"].get<int>() > 30; }, 60s)) << daemon.process.log();

  const httplib::Result anonymous = c.Post("/api/calibrate");
  ASSERT_TRUE(anonymous);
  EXPECT_EQ(anonymous->status, 401);
  EXPECT_THAT(anonymous->get_header_value("WWW-Authenticate"), HasSubstr("Bearer"));
  EXPECT_EQ(post(c, "/api/calibrate", "0123456789abcdef-wrong!!"), 403);
  EXPECT_EQ(post(c, "/api/record/start", std::string(kToken) + "x"), 403);
  EXPECT_EQ(post(c, "/api/output/disable"), 401);
  json s = fresh_state(c);
  EXPECT_EQ(s["commands"]["calibrate_requests"], 0);
  EXPECT_FALSE(s["status"]["recording"].get<bool>());
  EXPECT_TRUE(s["status"]["outputs_enabled"].get<bool>());
  EXPECT_TRUE(s["commands"]["enable_switch"].get<bool>()) << "no enable switch configured";
  EXPECT_EQ(s["monitor"]["refused"], 4);
  // A body sent in chunks (no length for the payload limit to refuse it by) is refused before
  // it is read, token or not.
  EXPECT_THAT(raw_exchange(daemon.port, "POST /api/calibrate HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n\r\n"
                                        "4\r\nabcd\r\n0\r\n\r\n"),
              ::testing::StartsWith("HTTP/1.1 413"));
  // A command without a length (curl -X POST without -d) is answered at once with how to send it,
  // not read until the client gives up.
  const std::string lengthless =
      raw_exchange(daemon.port, fmt::format("POST /api/calibrate HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {}\r\n"
                                            "Connection: close\r\n\r\n",
                                            kToken));
  EXPECT_THAT(lengthless, ::testing::StartsWith("HTTP/1.1 411"));
  EXPECT_THAT(lengthless, HasSubstr("Content-Length: 0 (curl -d '')"));
  // So is a request for byte ranges: one range asked for 700 times came back as 700 parts.
  std::string ranges = "GET / HTTP/1.1\r\nHost: x\r\n";
  for (int i = 0; i < 700; ++i) ranges += "Range: bytes=0-40000\r\n";
  const std::string ranged = raw_exchange(daemon.port, ranges + "\r\n");
  EXPECT_THAT(ranged, ::testing::StartsWith("HTTP/1.1 416"));
  EXPECT_LT(ranged.size(), 1000u);

  // Calibrate: the request is counted at once, the neutral capture completes on tracked frames.
  EXPECT_EQ(post(c, "/api/calibrate", kToken), 200);
  EXPECT_EQ(fresh_state(c)["commands"]["calibrate_requests"], 1);
  EXPECT_TRUE(wait_for([&] { return state(c)["commands"]["calibrations"] == 1; }, 20s)) << daemon.process.log();
  EXPECT_TRUE(wait_for([&] { return state(c)["status"]["calibrated"].get<bool>(); }, 5s));

  // Record: a take starts (the main thread acts on it) and stops.
  EXPECT_EQ(post(c, "/api/record/start", kToken), 200);
  EXPECT_TRUE(wait_for([&] { return state(c)["status"]["recording"].get<bool>(); }, 5s)) << daemon.process.log();
  EXPECT_EQ(post(c, "/api/record/stop", kToken), 200);
  EXPECT_TRUE(wait_for([&] { return !state(c)["status"]["recording"].get<bool>(); }, 5s)) << daemon.process.log();
  int takes = 0;
  for (const auto& entry : fs::directory_iterator(daemon.dir.path() / "takes"))
    takes += entry.path().extension() == ".csv";
  EXPECT_EQ(takes, 1);

  // Output enable: off drives the channels to neutral (the status word says so), on again.
  EXPECT_EQ(post(c, "/api/output/disable", kToken), 200);
  EXPECT_TRUE(wait_for([&] { return !state(c)["status"]["outputs_enabled"].get<bool>(); }, 5s));
  EXPECT_EQ(post(c, "/api/output/enable", kToken), 200);
  EXPECT_TRUE(wait_for([&] { return state(c)["status"]["outputs_enabled"].get<bool>(); }, 5s));

  s = fresh_state(c);
  EXPECT_EQ(s["monitor"]["commands"], 5);
  const std::string log = daemon.process.log();
  EXPECT_THAT(log, HasSubstr("monitor: calibrate refused (401) from 127.0.0.1"));
  EXPECT_THAT(log, HasSubstr("monitor: calibrate from 127.0.0.1"));
  daemon.stop();
}

TEST(MonitorHttp, AGeneratedTokenIsLoggedWithTheLinkAndWorks) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  MonitoredDaemon daemon;
  ASSERT_TRUE(daemon.process.wait_for_log("#token=")) << daemon.process.log();
  std::smatch m;
  const std::string log = daemon.process.log();
  ASSERT_TRUE(std::regex_search(
      log, m,
      std::regex(
          fmt::format(R"(monitor: control token ([0-9a-f]{{32}}): http://127\.0\.0\.1:{}/#token=\1)", daemon.port))))
      << log;
  auto c = client(daemon.port);
  EXPECT_EQ(post(c, "/api/calibrate", m[1]), 200);
  EXPECT_EQ(post(c, "/api/calibrate", "0123456789abcdef0123456789abcdef"), 403);
  daemon.stop();
}

/// A TCP connection that sends nothing: it holds a worker until the read times out.
class IdleConnection {
 public:
  explicit IdleConnection(int port) {
    fd_ = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_port = htons(static_cast<std::uint16_t>(port));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::connect(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
  }
  ~IdleConnection() { ::close(fd_); }
  IdleConnection(const IdleConnection&) = delete;
  IdleConnection& operator=(const IdleConnection&) = delete;

 private:
  int fd_ = -1;
};

TEST(MonitorHttp, ClientsBeyondTheBoundAreTurnedAwayAtOnce) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  MonitoredDaemon daemon("max_clients = 1");
  ASSERT_TRUE(daemon.listening()) << daemon.process.log();
  auto c = client(daemon.port);
  ASSERT_EQ(c.Get("/api/state")->status, 200);
  {
    // One connection the worker serves (it waits for a request), one waiting for the worker.
    const IdleConnection served(daemon.port);
    std::this_thread::sleep_for(200ms);
    const IdleConnection waiting(daemon.port);
    std::this_thread::sleep_for(200ms);
    const auto start = std::chrono::steady_clock::now();
    const httplib::Result turned_away = c.Get("/api/state");
    ASSERT_TRUE(turned_away);
    EXPECT_EQ(turned_away->status, 503);
    EXPECT_EQ(turned_away->get_header_value("Retry-After"), "1");
    EXPECT_LT(std::chrono::steady_clock::now() - start, 1s) << "answered by the listener, not queued";
  }
  // The idle connections close; the worker is free again.
  EXPECT_TRUE(wait_for(
      [&] {
        const httplib::Result r = c.Get("/api/state");
        return r && r->status == 200;
      },
      10s));
  EXPECT_GE(fresh_state(c)["monitor"]["turned_away"].get<int>(), 1);
  daemon.stop();
}

TEST(MonitorHttp, ATakenPortOrABadAddressIsLoggedAndTheDaemonRunsOn) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  const test::TempDir dir;
  const test::PortInUse taken;
  struct Case {
    std::string keys, message;
  };
  const Case cases[] = {
      {"", fmt::format("monitor: cannot listen on 127.0.0.1:{}: Address already in use; the daemon runs on without "
                       "the monitor page",
                       taken.port())},
      {"address = \"no such host.invalid\"",
       fmt::format("monitor: cannot listen on no such host.invalid:{}: the address does not resolve", taken.port())},
      {"address = \"192.0.2.1\"",  // TEST-NET-1: no interface of this machine has it
       fmt::format("monitor: cannot listen on 192.0.2.1:{}: Cannot assign requested address", taken.port())},
  };
  for (const Case& c : cases) {
    std::ofstream(dir.path() / "lipdrive.toml", std::ios::trunc) << monitor_config(dir.path(), taken.port(), c.keys);
    test::DaemonProcess daemon(dir.path() / "lipdrive.toml", dir.path() / "stderr.txt", "--frames 90 --stats");
    EXPECT_EQ(daemon.wait(120s), 0) << daemon.log();
    const std::string log = daemon.log();
    EXPECT_THAT(log, HasSubstr(c.message)) << log;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(log, m, std::regex(R"(processed (\d+))"))) << log;
    EXPECT_GE(std::stoi(m[1]), 90) << "the daemon ran on";
  }
}

TEST(MonitorConfig, LoopbackByDefaultAndOnInTheReferenceFile) {
  EXPECT_EQ(Config{}.monitor.address, "127.0.0.1");
  EXPECT_FALSE(Config{}.monitor.enabled) << "a file without [monitor] serves no page";
  // The shipped file (test_config checks that it is valid): its [monitor] table.
  std::ifstream in(fs::path(test::kSourceDir) / "config" / "lipdrive.toml");
  const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  const std::string table = text.substr(text.find("\n[monitor]\n"));
  const std::string keys = table.substr(0, table.find("\n[", 1));
  EXPECT_THAT(keys, HasSubstr("\nenabled = true\n"));
  EXPECT_THAT(keys, HasSubstr("\naddress = \"127.0.0.1\"\n"));
  EXPECT_THAT(keys, HasSubstr("\ntoken = \"\"\n")) << "generated at start";
}

TEST(MonitorConfig, BadKeysAreConfigurationErrors) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  const test::TempDir dir;
  const struct {
    std::string keys, message;
  } cases[] = {
      {"port = 0", "key monitor.port: must be between 1 and 65535, got 0"},
      {"token = \"short\"", "key monitor.token: must be at least 16 letters"},
      {"token = \"0123456789abcdef 0123\"", "key monitor.token: must be at least 16 letters"},
      {"preview_fps = 0", "key monitor.preview_fps: must be between 1 and 30"},
      {"max_clients = 100", "key monitor.max_clients: must be between 1 and 64"},
      {"colour = \"blue\"", "monitor.colour"},
  };
  for (const auto& c : cases) {
    const fs::path file = dir.path() / "bad.toml";
    std::ofstream(file, std::ios::trunc) << test::sim_camera_at_60_fps() << "[monitor]\nenabled = true\n"
                                         << c.keys << "\n";
    const auto run = test::run_command(fmt::format("{} check-config {}", test::kLipdrive, file.string()));
    EXPECT_EQ(run.exit_code, 78) << c.keys << ": " << run.output;
    EXPECT_THAT(run.output, HasSubstr(c.message)) << c.keys;
  }
}

// ---------------------------------------------------------------- the page in a browser

const fs::path kBrowserArtifacts = fs::path(test::kBuildDir) / "test_artifacts" / "monitor";

/// The part of a screenshot where the element `box` (CSS pixels, scale 1) is.
cv::Mat region(const cv::Mat& screenshot, const json& box) {
  const cv::Rect r(box["x"].get<int>(), box["y"].get<int>(), box["width"].get<int>(), box["height"].get<int>());
  return screenshot(r & cv::Rect(0, 0, screenshot.cols, screenshot.rows));
}

cv::Mat decode_png(const std::string& png) {
  return cv::imdecode(std::vector<unsigned char>(png.begin(), png.end()), cv::IMREAD_COLOR);
}

/// Two screenshots of the page a second apart, kept as NAME-1.png and NAME-2.png.
std::pair<cv::Mat, cv::Mat> two_screenshots(test::WebDriver& browser, const std::string& name) {
  fs::create_directories(kBrowserArtifacts);
  const std::string first = browser.screenshot_png();
  std::this_thread::sleep_for(1s);
  const std::string second = browser.screenshot_png();
  std::ofstream(kBrowserArtifacts / (name + "-1.png"), std::ios::binary) << first;
  std::ofstream(kBrowserArtifacts / (name + "-2.png"), std::ios::binary) << second;
  return {decode_png(first), decode_png(second)};
}

/// Whether the element `box` shows another picture in `second` than in `first`, or else in a
/// screenshot taken within three seconds after. The clips rest between their sentences with one
/// and the same still face, so two screenshots a second apart can show the same picture (frames
/// 335 and 419 once: two rests of the looped clip).
bool shows_another_picture(test::WebDriver& browser, const cv::Mat& first, const cv::Mat& second, const json& box) {
  const auto differs = [&](const cv::Mat& later) {
    return cv::norm(region(first, box), region(later, box), cv::NORM_L1) > 0;
  };
  bool another = differs(second);
  for (int retry = 0; retry < 6 && !another; ++retry) {
    std::this_thread::sleep_for(500ms);
    another = differs(decode_png(browser.screenshot_png()));
  }
  return another;
}

TEST(MonitorBrowser, ThePageUpdatesAndItsCalibrateButtonNeedsTheToken) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  MonitoredDaemon daemon(fmt::format("token = \"{}\"", kToken));
  ASSERT_TRUE(daemon.listening()) << daemon.process.log();
  test::WebDriver browser(daemon.dir.path(), test::free_port());
  ASSERT_TRUE(browser.ok()) << browser.why();
  auto c = client(daemon.port);
  const std::string page = fmt::format("http://127.0.0.1:{}/", daemon.port);
  browser.go(page);
  // The page has shown the state once the counters are numbers.
  const auto shown = [&](const std::string& id) {
    const json text = browser.execute(fmt::format("return document.getElementById('{}').textContent;", id));
    return text.is_string() ? text.get<std::string>() : std::string();
  };
  ASSERT_TRUE(wait_for(
      [&] {
        return std::isdigit(static_cast<unsigned char>(shown("tracked").c_str()[0])) &&
               std::stoi(shown("tracked")) > 30;
      },
      60s))
      << daemon.process.log();
  // A preview and two seconds of plot, then the first screenshot; the second a second later.
  ASSERT_TRUE(
      wait_for([&] { return browser.execute("return document.getElementById('preview').naturalWidth;") == 640; }, 20s));
  std::this_thread::sleep_for(2s);
  const auto [first, second] = two_screenshots(browser, "page");
  ASSERT_FALSE(first.empty());
  ASSERT_EQ(first.size(), second.size());
  const json preview_box = browser.rect("#preview"), plots_box = browser.rect("#plots");
  EXPECT_GT(preview_box["width"].get<double>(), 300);
  EXPECT_GT(plots_box["height"].get<double>(), 200);
  EXPECT_TRUE(shows_another_picture(browser, first, second, preview_box)) << "the image updates";
  EXPECT_GT(cv::norm(region(first, plots_box), region(second, plots_box), cv::NORM_L1), 0) << "the plots move";
  // The plotted curve spans more than the strip's middle: the open channel moves over 10 s.
  const json drawn = browser.execute("const v = samples.values[0]; return [v.length, Math.min(...v), Math.max(...v)];");
  EXPECT_GT(drawn[0].get<int>(), 50);
  EXPECT_GT(drawn[2].get<double>() - drawn[1].get<double>(), 10);

  // What the page shows is the daemon's state: the counters lie between two reads of the JSON.
  const json before = fresh_state(c);
  const int processed = std::stoi(shown("processed"));
  const json after = fresh_state(c);
  EXPECT_LE(before["frames"]["processed"].get<int>() - 20, processed) << "the page polls 4 times a second";
  EXPECT_LE(processed, after["frames"]["processed"].get<int>());
  EXPECT_EQ(shown("calibrate_requests"), "0");
  EXPECT_EQ(shown("lost_track"), std::to_string(after["frames"]["lost_track"].get<int>()));

  // Read-only without the token: calibrate is refused, nothing changes.
  EXPECT_THAT(shown("access"), HasSubstr("read-only"));
  browser.click("#calibrate");
  EXPECT_TRUE(wait_for([&] { return shown("message") == "calibrate: refused (401)"; }, 5s)) << shown("message");
  EXPECT_EQ(fresh_state(c)["commands"]["calibrate_requests"], 0);

  // With the token from the logged link: it is kept for the tab and dropped from the address.
  browser.go(page + "#token=" + kToken);
  EXPECT_TRUE(wait_for([&] { return shown("access") == "control token set"; }, 10s)) << shown("access");
  EXPECT_EQ(browser.execute("return location.hash;"), "");
  browser.click("#calibrate");
  EXPECT_TRUE(wait_for([&] { return shown("message") == "calibrate: sent"; }, 5s)) << shown("message");
  EXPECT_TRUE(wait_for([&] { return shown("calibrate_requests") == "1"; }, 5s));
  EXPECT_EQ(fresh_state(c)["commands"]["calibrate_requests"], 1);
  EXPECT_TRUE(wait_for([&] { return shown("calibrations") == "1"; }, 20s)) << daemon.process.log();
  const std::string last_png = browser.screenshot_png();
  std::ofstream(kBrowserArtifacts / "page-calibrated.png", std::ios::binary) << last_png;
  daemon.stop();
}

/// Pixels of the overlay's colours in a screenshot of a grey camera image: the browser scales the
/// image, so the thin lines blend with the grey below them; what stands out is their chroma.
bool yellowish(const cv::Vec3b& p) { return p[2] - p[0] > 80 && p[1] - p[0] > 80; }
bool magentaish(const cv::Vec3b& p) { return p[2] - p[1] > 60 && p[0] - p[1] > 60; }
bool greenish(const cv::Vec3b& p) { return p[1] - p[2] > 60 && p[1] - p[0] > 60; }
struct OverlayPixels {
  int yellow = 0, magenta = 0, green = 0;
};
OverlayPixels overlay_pixels(const cv::Mat& image) {
  OverlayPixels n;
  for (auto it = image.begin<cv::Vec3b>(); it != image.end<cv::Vec3b>(); ++it) {
    n.yellow += yellowish(*it);
    n.magenta += magentaish(*it);
    n.green += greenish(*it);
  }
  return n;
}

/// Where the side image's nose tip is drawn: the centre of the yellow pixels within 6 px of the
/// rightmost one (the head looks right; the tip is the profile's foremost point). (-1, -1) when
/// nothing yellow is drawn.
cv::Point2d drawn_nose_tip(const cv::Mat& image) {
  std::vector<cv::Point> yellow;
  for (int y = 0; y < image.rows; ++y)
    for (int x = 0; x < image.cols; ++x)
      if (yellowish(image.at<cv::Vec3b>(y, x))) yellow.emplace_back(x, y);
  if (yellow.empty()) return {-1, -1};
  const int foremost = std::ranges::max(yellow, {}, &cv::Point::x).x;
  cv::Point2d sum(0, 0);
  int n = 0;
  for (const cv::Point& p : yellow) {
    if (p.x < foremost - 6) continue;
    sum += cv::Point2d(p);
    ++n;
  }
  return sum / n;
}

/// Pixels of the rendered face (grey) and of the background (black) within `radius` of `centre`.
std::pair<int, int> face_and_background_near(const cv::Mat& image, const cv::Point2d& centre, int radius) {
  int face = 0, background = 0;
  const cv::Rect window = cv::Rect(cv::Point(static_cast<int>(centre.x) - radius, static_cast<int>(centre.y) - radius),
                                   cv::Size(2 * radius + 1, 2 * radius + 1)) &
                          cv::Rect(0, 0, image.cols, image.rows);
  for (int y = window.y; y < window.br().y; ++y)
    for (int x = window.x; x < window.br().x; ++x) {
      const cv::Vec3b p = image.at<cv::Vec3b>(y, x);
      const bool grey = std::abs(p[0] - p[1]) < 20 && std::abs(p[1] - p[2]) < 20;
      face += grey && p[1] > 60;
      background += grey && p[1] < 30;
    }
  return {face, background};
}

// With a side camera the page shows its image under the front camera's, both updating, each with
// its overlay; the side image's nose tip is drawn on the profile's edge.
TEST(MonitorBrowser, ShowsTheSideCameraBesideTheFrontAndBothUpdate) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  LIPDRIVE_REQUIRE_BUILT(kSideClip);
  MonitoredDaemon daemon("", side_camera_table());
  ASSERT_TRUE(daemon.listening()) << daemon.process.log();
  test::WebDriver browser(daemon.dir.path(), test::free_port());
  ASSERT_TRUE(browser.ok()) << browser.why();
  browser.set_window_size(1280, 1400);  // both images in the viewport, one above the other
  browser.go(fmt::format("http://127.0.0.1:{}/", daemon.port));
  const auto natural_width = [&](const std::string& id) {
    return browser.execute(fmt::format("return document.getElementById('{}').naturalWidth;", id));
  };
  ASSERT_TRUE(wait_for([&] { return natural_width("preview") == 640 && natural_width("side-preview") == 640; }, 60s))
      << daemon.process.log();
  EXPECT_EQ(browser.execute("return document.getElementById('side-section').hidden;"), false);
  std::this_thread::sleep_for(1s);
  const auto [first, second] = two_screenshots(browser, "page-side");
  ASSERT_FALSE(first.empty());
  ASSERT_EQ(first.size(), second.size());
  const json front_box = browser.rect("#preview"), side_box = browser.rect("#side-preview");
  EXPECT_GT(side_box["y"].get<double>(), front_box["y"].get<double>() + front_box["height"].get<double>());
  ASSERT_LE(side_box["y"].get<double>() + side_box["height"].get<double>(), first.rows) << "the side image is shown";
  EXPECT_GT(side_box["width"].get<double>(), 300);
  EXPECT_TRUE(shows_another_picture(browser, first, second, front_box)) << "the front image updates";
  EXPECT_TRUE(shows_another_picture(browser, first, second, side_box)) << "the side image updates";

  for (const cv::Mat* screenshot : {&first, &second}) {
    // The front camera's overlay: the face box in yellow, the fitted lips in magenta, the 68
    // landmarks in green.
    const OverlayPixels front = overlay_pixels(region(*screenshot, front_box));
    EXPECT_GT(front.yellow, 600) << "the face box";
    EXPECT_GT(front.magenta, 300) << "the fitted lips' two contours";
    EXPECT_GT(front.green, 68 * 5) << "the landmarks";
    // The side camera's: the nose in yellow, the subnasale in green, the upper lip in magenta; the
    // nose tip on the edge between the rendered head and the background (an overlay scaled or
    // shifted off the image would lie on one side of it).
    const cv::Mat side_image = region(*screenshot, side_box);
    const OverlayPixels side = overlay_pixels(side_image);
    EXPECT_GT(side.yellow, 60) << "the nose";
    EXPECT_GT(side.green, 10) << "the subnasale";
    EXPECT_GT(side.magenta, 20) << "the upper lip";
    const cv::Point2d tip = drawn_nose_tip(side_image);
    const auto [face, background] = face_and_background_near(side_image, tip, 10);
    EXPECT_GT(face, 60) << "nose tip drawn at " << tip;
    EXPECT_GT(background, 60) << "nose tip drawn at " << tip;
    std::printf("front overlay: %d yellow, %d magenta, %d green pixels; side: %d, %d, %d; side nose tip drawn at "
                "(%.1f, %.1f), %d face and %d background pixels within 10 px\n",
                front.yellow, front.magenta, front.green, side.yellow, side.magenta, side.green, tip.x, tip.y, face,
                background);
  }
  daemon.stop();
}

// In the test's own process, so that the daemon's counters can be read beside the page.
TEST(MonitorState, AfterStopTheStateEqualsTheDaemonsCounters) {
  LIPDRIVE_REQUIRE_BUILT(kClip);
  const test::TempDir dir;
  const int port = test::free_port();
  std::ofstream(dir.path() / "lipdrive.toml") << monitor_config(dir.path(), port);
  Config config = load_config(dir.path() / "lipdrive.toml");
  static LoadedFiles files;
  PerformerProfile profile = load_performer(config);
  auto processor = make_processor(config, files, profile);
  Daemon daemon(std::move(config), std::move(profile), std::move(processor), DaemonOptions{}, files);
  ASSERT_TRUE(wait_for(
      [&] {
        daemon.poll();
        return daemon.stats().processed >= 120;
      },
      60s));
  auto c = client(port);
  EXPECT_EQ(post(c, "/api/calibrate"), 401);
  daemon.stop();
  const PipelineStats s = daemon.stats();
  const json page = fresh_state(c);
  const json& frames = page["frames"];
  EXPECT_EQ(frames["captured"], s.captured);
  EXPECT_EQ(frames["processed"], s.processed);
  EXPECT_EQ(frames["tracked"], s.tracked);
  EXPECT_EQ(frames["dropped"], s.dropped);
  EXPECT_EQ(frames["lost_track"], s.lost_track);
  EXPECT_EQ(frames["disconnects"], s.disconnects);
  EXPECT_EQ(frames["corrupt"], s.corrupt);
  EXPECT_EQ(page["latency_ms"]["processed"]["median"].get<double>(), s.processed_median_ms);
  EXPECT_EQ(page["latency_ms"]["processed"]["p99"].get<double>(), s.processed_p99_ms);
  EXPECT_EQ(page["latency_ms"]["output"]["median"].get<double>(), s.output_median_ms);
  EXPECT_EQ(page["latency_ms"]["output"]["p99"].get<double>(), s.output_p99_ms);
  // Stopped: the last drive frame is the neutral pose.
  EXPECT_EQ(page["channels"][0]["value"].get<double>(), 0);
  EXPECT_EQ(page["channels"][1]["value"].get<double>(), 500);
  EXPECT_FALSE(page["status"]["tracking"].get<bool>());
  EXPECT_EQ(page["source"], "fail-safe") << "who drives: the status word's source";
  EXPECT_EQ(page["monitor"]["refused"], 1);
}

}  // namespace
}  // namespace lipdrive
