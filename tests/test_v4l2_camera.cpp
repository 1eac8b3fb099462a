// The V4L2 driver against a fake device behind the system-call seam, plus one check that
// the real system calls fail cleanly.
#include "drivers/chroma_420.hpp"
#include "drivers/clock.hpp"
#include "drivers/v4l2_camera.hpp"
#include "tests/allocation_counter.hpp"
#include "tests/captured_log.hpp"
#include "tests/fake_v4l2_device.hpp"

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include <array>
#include <chrono>
#include <limits>
#include <ostream>
#include <string>
#include <thread>
#include <vector>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;
using testing::CapturedLog;
using testing::FakeV4l2Device;
using testing::test_pattern;
using testing::expected_cr;
using Clock = std::chrono::steady_clock;

// How late a grab may return after its timeout: on a shared 2-core machine at load 11,
// wake-ups from sleep were measured up to ~110 ms late.
constexpr auto kSlack = 250ms;

V4l2Options options_for(const FakeV4l2Device::Config& config, PixelFormat format = PixelFormat::kAuto) {
  V4l2Options options;
  options.device = config.path;
  options.format = format;
  options.reconnect_initial = 5ms;
  options.reconnect_max = 20ms;
  return options;
}

std::string error_of(const FakeV4l2Device::Config& config, const V4l2Options& options) {
  FakeV4l2Device device(config);
  try {
    V4l2Camera camera(options, device);
  } catch (const SourceError& error) {
    return error.what();
  }
  return "(no error)";
}

// The kernel's rules hold after every test: no leaks, no misuse.
void expect_clean(const FakeV4l2Device& device) {
  EXPECT_EQ(device.open_fd_count(), 0u);
  EXPECT_EQ(device.mapping_count(), 0u);
  for (const std::string& violation : device.violations()) ADD_FAILURE() << "V4L2 rule broken: " << violation;
}

// ---- negotiation ------------------------------------------------------------------------

TEST(V4l2Negotiation, HonoursTheRequestedFormat) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
  FakeV4l2Device device(config);
  {
    V4l2Camera camera(options_for(config, PixelFormat::kMjpeg), device);
    EXPECT_EQ(camera.negotiated().format, PixelFormat::kMjpeg);
    EXPECT_EQ(device.pixel_format(), V4L2_PIX_FMT_MJPEG);
    EXPECT_TRUE(device.streaming());
    EXPECT_EQ(camera.negotiated().card, "Fake V4L2 camera");
  }
  expect_clean(device);
}

TEST(V4l2Negotiation, AutoPrefersNv12ThenYuyvThenGreyThenMjpeg) {
  struct Case {
    std::vector<std::uint32_t> offered;
    PixelFormat expected;
  };
  const std::vector<Case> cases = {
      {{V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_NV12, V4L2_PIX_FMT_GREY}, PixelFormat::kNv12},
      {{V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_YUYV}, PixelFormat::kYuyv},
      {{V4L2_PIX_FMT_MJPEG, V4L2_PIX_FMT_RGB24, V4L2_PIX_FMT_GREY}, PixelFormat::kGrey},
      {{V4L2_PIX_FMT_H264, V4L2_PIX_FMT_MJPEG}, PixelFormat::kMjpeg},
  };
  for (const Case& c : cases) {
    FakeV4l2Device::Config config;
    config.formats = c.offered;
    FakeV4l2Device device(config);
    V4l2Camera camera(options_for(config), device);
    EXPECT_EQ(camera.negotiated().format, c.expected) << pixel_format_name(c.expected);
  }
}

TEST(V4l2Negotiation, UnofferedFormatIsAnErrorNamingTheDevice) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_YUYV};
  const std::string message = error_of(config, options_for(config, PixelFormat::kGrey));
  EXPECT_NE(message.find(config.path), std::string::npos) << message;
  EXPECT_NE(message.find("GREY"), std::string::npos) << message;
  EXPECT_NE(message.find("YUYV"), std::string::npos) << message;  // what it does offer
}

TEST(V4l2Negotiation, NoUsableFormatIsAnErrorNamingTheDevice) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_H264, V4L2_PIX_FMT_RGB24};
  const std::string message = error_of(config, options_for(config));
  EXPECT_NE(message.find(config.path), std::string::npos) << message;
  EXPECT_NE(message.find("H264"), std::string::npos) << message;
}

TEST(V4l2Negotiation, NonCaptureDeviceIsAnErrorNamingTheDevice) {
  FakeV4l2Device::Config config;
  config.capabilities = V4L2_CAP_VIDEO_OUTPUT | V4L2_CAP_STREAMING;
  const std::string message = error_of(config, options_for(config));
  EXPECT_NE(message.find(config.path), std::string::npos) << message;
  EXPECT_NE(message.find("capture"), std::string::npos) << message;

  config.capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_READWRITE;
  EXPECT_NE(error_of(config, options_for(config)).find("streaming"), std::string::npos);
}

/// Plugs the device back in and grabs until the camera has reopened it: the sensor has not
/// captured yet, so the grab that reopens it times out.
void replug_and_reopen(FakeV4l2Device& device, V4l2Camera& camera) {
  device.replug();
  Frame frame;
  GrabStatus status = GrabStatus::kDisconnected;
  for (int attempt = 0; attempt < 20 && status == GrabStatus::kDisconnected; ++attempt)
    status = camera.grab(frame, 20ms);
  ASSERT_EQ(status, GrabStatus::kTimeout);
  EXPECT_TRUE(camera.connected());
  EXPECT_TRUE(camera.reconnect_error().empty());
}

// A camera not there when the daemon starts (a USB camera enumerated after it at boot) is a
// camera away, named and waited for as after an unplug: frames flow once it appears.
TEST(V4l2Disconnect, ACameraNotThereYetIsWaitedFor) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_GREY};
  FakeV4l2Device device(config);
  device.unplug();
  V4l2Options options = options_for(config);
  options.frame_rate = 60;
  V4l2Camera camera(options, device);
  EXPECT_FALSE(camera.connected());
  EXPECT_NE(camera.reconnect_error().find(config.path), std::string::npos) << camera.reconnect_error();
  EXPECT_DOUBLE_EQ(camera.frame_rate(), 60) << "the rate asked for until a stream says otherwise";
  Frame frame;
  for (int attempt = 0; attempt < 5; ++attempt) EXPECT_EQ(camera.grab(frame, 20ms), GrabStatus::kDisconnected);
  EXPECT_EQ(device.open_fd_count(), 0u);

  ASSERT_NO_FATAL_FAILURE(replug_and_reopen(device, camera));
  const cv::Mat expected = test_pattern(device.size(), 3);
  ASSERT_TRUE(device.produce(expected));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  EXPECT_EQ(cv::norm(frame.gray, expected, cv::NORM_INF), 0);
  EXPECT_TRUE(device.violations().empty());
}

// At boot udev gives a new node its group a moment after it appears: until then opening it is
// refused, and the camera is waited for as one not there yet.
TEST(V4l2Disconnect, ANodeNotYetTheServicesToOpenIsWaitedFor) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_GREY};
  FakeV4l2Device device(config);
  device.refuse_open(EACCES);
  V4l2Camera camera(options_for(config), device);
  EXPECT_FALSE(camera.connected());
  EXPECT_NE(camera.reconnect_error().find("Permission denied"), std::string::npos) << camera.reconnect_error();
  device.refuse_open(0);
  ASSERT_NO_FATAL_FAILURE(replug_and_reopen(device, camera));
  EXPECT_TRUE(device.violations().empty());
}

TEST(V4l2Negotiation, AcceptsTheSizeAndRateTheDriverAdjustedTo) {
  FakeV4l2Device::Config config;
  config.sizes = {{640, 480}, {320, 240}};
  config.frame_rates = {30, 15};
  config.row_padding = 64;
  FakeV4l2Device device(config);
  V4l2Options options = options_for(config, PixelFormat::kYuyv);
  options.width = 300;
  options.height = 200;
  options.frame_rate = 14;
  V4l2Camera camera(options, device);
  EXPECT_EQ(camera.negotiated().width, 320u);
  EXPECT_EQ(camera.negotiated().height, 240u);
  EXPECT_EQ(camera.negotiated().bytes_per_line, 2 * 320u + 64);
  EXPECT_EQ(camera.negotiated().bytes_per_line, device.bytes_per_line());
  EXPECT_DOUBLE_EQ(camera.negotiated().frame_rate, 15.0);
  EXPECT_DOUBLE_EQ(camera.frame_rate(), 15.0);
  EXPECT_GE(camera.negotiated().buffer_count, 2u);
}

TEST(V4l2Negotiation, KeepsThePowerOnSizeAndRateWhenNoneIsRequested) {
  FakeV4l2Device::Config config;
  config.sizes = {{160, 120}, {320, 240}};
  config.frame_rates = {25, 50};
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  EXPECT_EQ(camera.negotiated().width, 160u);
  EXPECT_EQ(camera.negotiated().height, 120u);
  EXPECT_DOUBLE_EQ(camera.frame_rate(), 25.0);
}

TEST(V4l2Negotiation, ResolvesByIdNames) {
  FakeV4l2Device::Config config;
  config.path = "/dev/v4l/by-id/usb-Fake_Cam-video-index0";
  FakeV4l2Device device(config);
  V4l2Options options = options_for(config);
  options.device = "usb-Fake_Cam-video-index0";
  V4l2Camera camera(options, device);
  EXPECT_EQ(camera.describe(), config.path);
}

// ---- image controls --------------------------------------------------------------------

/// A UVC camera's exposure, gain, anti-flicker and exposure-priority controls, at their
/// power-on values (automatic exposure may lower the frame rate).
std::vector<v4l2_queryctrl> uvc_controls() {
  const auto control = [](std::uint32_t id, std::int32_t min, std::int32_t max, std::int32_t value) {
    v4l2_queryctrl query{};
    query.id = id;
    query.minimum = min;
    query.maximum = max;
    query.step = 1;
    query.default_value = value;
    return query;
  };
  return {control(V4L2_CID_EXPOSURE_AUTO, 0, 3, V4L2_EXPOSURE_APERTURE_PRIORITY),
          control(V4L2_CID_EXPOSURE_ABSOLUTE, 3, 2047, 250), control(V4L2_CID_GAIN, 0, 255, 64),
          control(V4L2_CID_POWER_LINE_FREQUENCY, 0, 2, V4L2_CID_POWER_LINE_FREQUENCY_60HZ),
          control(V4L2_CID_EXPOSURE_AUTO_PRIORITY, 0, 1, 1)};
}

void expect_controls_set(const FakeV4l2Device& device) {
  EXPECT_EQ(device.control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_MANUAL);
  EXPECT_EQ(device.control(V4L2_CID_EXPOSURE_ABSOLUTE), 40) << "4 ms in 100 µs steps";
  EXPECT_EQ(device.control(V4L2_CID_GAIN), 12);
  EXPECT_EQ(device.control(V4L2_CID_POWER_LINE_FREQUENCY), V4L2_CID_POWER_LINE_FREQUENCY_50HZ);
  EXPECT_EQ(device.control(V4L2_CID_EXPOSURE_AUTO_PRIORITY), 0);
}

TEST(V4l2Controls, AreSetOnOpenAndAgainWhenTheCameraComesBack) {
  FakeV4l2Device::Config config;
  config.controls = uvc_controls();
  FakeV4l2Device device(config);
  V4l2Options options = options_for(config);
  options.controls = {.exposure_us = 4000, .gain = 12, .power_line_hz = 50};
  {
    V4l2Camera camera(options, device);
    expect_controls_set(device);
    // A replugged camera is back at its power-on values until the driver sets them again.
    device.unplug();
    device.replug();
    EXPECT_EQ(device.control(V4L2_CID_GAIN), 64);
    Frame frame;
    GrabStatus status = GrabStatus::kDisconnected;
    for (int attempt = 0; attempt < 20 && status != GrabStatus::kTimeout; ++attempt) status = camera.grab(frame, 20ms);
    ASSERT_EQ(status, GrabStatus::kTimeout) << "reopened";
    expect_controls_set(device);
  }
  expect_clean(device);

  // Nothing asked for: the camera's own settings stay.
  FakeV4l2Device untouched(config);
  V4l2Options as_it_is = options_for(config);
  as_it_is.controls.keep_frame_rate = false;
  { V4l2Camera camera(as_it_is, untouched); }
  EXPECT_EQ(untouched.control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_APERTURE_PRIORITY);
  EXPECT_EQ(untouched.control(V4L2_CID_GAIN), 64);
  EXPECT_EQ(untouched.control(V4L2_CID_EXPOSURE_AUTO_PRIORITY), 1);
  expect_clean(untouched);
}

TEST(V4l2Controls, ByDefaultAutomaticExposureMayNotLowerTheFrameRate) {
  FakeV4l2Device::Config config;
  config.controls = uvc_controls();
  FakeV4l2Device device(config);
  CapturedLog log;
  { V4l2Camera camera(options_for(config), device); }
  EXPECT_EQ(device.control(V4L2_CID_EXPOSURE_AUTO_PRIORITY), 0) << "the frame rate held";
  EXPECT_EQ(device.control(V4L2_CID_EXPOSURE_AUTO), V4L2_EXPOSURE_APERTURE_PRIORITY) << "exposure still automatic";
  EXPECT_EQ(device.control(V4L2_CID_GAIN), 64);
  expect_clean(device);

  // A camera without the control (a CSI sensor, most non-UVC drivers): nothing to say.
  config.controls.pop_back();
  FakeV4l2Device plain(config);
  { V4l2Camera camera(options_for(config), plain); }
  EXPECT_TRUE(log.messages(spdlog::level::warn).empty());
  expect_clean(plain);
}

TEST(V4l2Controls, AMissingControlOrAValueOutOfRangeIsLoggedAndFramesFlow) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_GREY};
  config.controls = uvc_controls();
  config.controls.erase(config.controls.begin() + 2);  // no gain
  FakeV4l2Device device(config);
  V4l2Options options = options_for(config);
  options.controls = {.exposure_us = 500'000, .gain = 12, .power_line_hz = 0};
  CapturedLog log;
  {
    V4l2Camera camera(options, device);
    EXPECT_EQ(device.control(V4L2_CID_EXPOSURE_ABSOLUTE), 2047) << "clamped to the camera's longest";
    EXPECT_EQ(device.control(V4L2_CID_POWER_LINE_FREQUENCY), V4L2_CID_POWER_LINE_FREQUENCY_DISABLED);
    const std::vector<std::string> warnings = log.messages(spdlog::level::warn);
    ASSERT_EQ(warnings.size(), 2u);
    EXPECT_EQ(warnings[0], config.path + ": exposure_absolute (100 µs) 5000 is outside the camera's range 3..2047; set to 2047");
    EXPECT_EQ(warnings[1], config.path + ": the camera has no control gain; left as the camera sets it");
    Frame frame;
    ASSERT_TRUE(device.produce(test_pattern(device.size(), 1)));
    EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  }
  expect_clean(device);
}

TEST(V4l2Negotiation, ParsesPixelFormatNames) {
  EXPECT_EQ(parse_pixel_format("yuyv"), PixelFormat::kYuyv);
  EXPECT_EQ(parse_pixel_format("MJPEG"), PixelFormat::kMjpeg);
  EXPECT_EQ(parse_pixel_format("Auto"), PixelFormat::kAuto);
  EXPECT_THROW(parse_pixel_format("RGB3"), std::invalid_argument);
}

// ---- luma and Cr extraction ---------------------------------------------------------------

struct LumaCase {
  std::uint32_t fourcc;
  PixelFormat format;
  unsigned row_padding;
  double max_error;  // JPEG is lossy; the raw formats must be exact
};

void PrintTo(const LumaCase& luma_case, std::ostream* out) {
  *out << pixel_format_name(luma_case.format) << " with " << luma_case.row_padding << " bytes of row padding";
}

class V4l2Luma : public ::testing::TestWithParam<LumaCase> {};

TEST_P(V4l2Luma, DeliversTheLumaAndCrPlanesOfEachFrame) {
  FakeV4l2Device::Config config;
  config.formats = {GetParam().fourcc};
  config.row_padding = GetParam().row_padding;
  FakeV4l2Device device(config);
  {
    V4l2Camera camera(options_for(config, GetParam().format), device);
    for (int seed = 0; seed < 3; ++seed) {
      const cv::Mat expected = test_pattern(device.size(), seed);
      ASSERT_TRUE(device.produce(expected));
      Frame frame;
      ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
      ASSERT_EQ(frame.gray.type(), CV_8UC1);
      ASSERT_EQ(frame.gray.size(), expected.size());
      EXPECT_LE(cv::norm(frame.gray, expected, cv::NORM_INF), GetParam().max_error) << "frame " << seed;
      const cv::Mat cr = expected_cr(expected, GetParam().fourcc);
      ASSERT_EQ(frame.cr.empty(), cr.empty()) << "a Cr plane exactly where the format carries one";
      if (!cr.empty()) {
        ASSERT_EQ(frame.cr.size(), cr.size());
        EXPECT_EQ(cv::norm(frame.cr, cr, cv::NORM_INF), 0) << "frame " << seed;
      }
      EXPECT_EQ(frame.sequence, std::uint64_t(seed));
      EXPECT_EQ(frame.source, config.path);
    }
  }
  expect_clean(device);
}

INSTANTIATE_TEST_SUITE_P(Formats, V4l2Luma,
                         ::testing::Values(LumaCase{V4L2_PIX_FMT_YUYV, PixelFormat::kYuyv, 32, 0},
                                           LumaCase{V4L2_PIX_FMT_GREY, PixelFormat::kGrey, 0, 0},
                                           LumaCase{V4L2_PIX_FMT_GREY, PixelFormat::kGrey, 48, 0},
                                           LumaCase{V4L2_PIX_FMT_NV12, PixelFormat::kNv12, 64, 0},
                                           LumaCase{V4L2_PIX_FMT_MJPEG, PixelFormat::kMjpeg, 0, 8}),
                         [](const auto& info) {
                           return std::string(pixel_format_name(info.param.format)) + "_padding" +
                                  std::to_string(info.param.row_padding);
                         });

TEST(V4l2Luma, AnInterlacedDriversFramesAreReadFromTheirFirstField) {
  // An analogue grabber's frames hold two fields, captured 20 ms apart, in alternate rows (or
  // one after the other): the first field in time (the top one, or the bottom one where the
  // driver says so or, for V4L2_FIELD_INTERLACED, where the standard is NTSC's 480 lines)
  // holds a picture, the other its negative. Read, each frame is the picture alone, at the
  // frame's size, and a frame after the first allocates nothing.
  struct Case {
    std::uint32_t field;
    cv::Size size;
    int first_row;  // of the first field; -1: the fields one after the other
  };
  for (const Case c : {Case{V4L2_FIELD_INTERLACED_TB, {320, 240}, 0}, Case{V4L2_FIELD_INTERLACED_BT, {320, 240}, 1},
                       Case{V4L2_FIELD_INTERLACED, {320, 240}, 0}, Case{V4L2_FIELD_INTERLACED, {640, 480}, 1},
                       Case{V4L2_FIELD_SEQ_TB, {320, 240}, -1}}) {
    for (const std::uint32_t fourcc : {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_NV12}) {
      SCOPED_TRACE(::testing::Message() << "field " << c.field << ", " << c.size << ", format " << fourcc);
      FakeV4l2Device::Config config;
      config.formats = {fourcc};
      config.sizes = {c.size};
      config.field = c.field;
      FakeV4l2Device device(config);
      V4l2Camera camera(options_for(config), device);
      cv::Mat picture(c.size, CV_8UC1);
      for (int x = 0; x < c.size.width; ++x) picture.col(x).setTo(16 + 200 * x / c.size.width);
      cv::Mat frame_rows = 255 - picture;
      if (c.first_row < 0) picture.rowRange(0, c.size.height / 2).copyTo(frame_rows.rowRange(0, c.size.height / 2));
      for (int y = c.first_row; y >= 0 && y < c.size.height; y += 2) picture.row(y).copyTo(frame_rows.row(y));
      Frame frame;
      ASSERT_TRUE(device.produce(frame_rows));
      ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);  // the first allocates the field's planes
      ASSERT_TRUE(device.produce(frame_rows));
      lipdrive::test::count_allocations_on_this_thread(true);
      const long before = lipdrive::test::allocation_count();
      ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
      const long allocations = lipdrive::test::allocation_count() - before;
      lipdrive::test::count_allocations_on_this_thread(false);
      EXPECT_EQ(allocations, 0);
      ASSERT_EQ(frame.gray.size(), c.size);
      EXPECT_LE(cv::norm(frame.gray, picture, cv::NORM_INF), 1);  // the fields combed: 223
      if (fourcc == V4L2_PIX_FMT_YUYV) {  // its Cr has a row per frame row (the fake's NV12 takes it from even rows)
        const cv::Mat cr = expected_cr(picture, fourcc);
        ASSERT_EQ(frame.cr.size(), cr.size());
        EXPECT_LE(cv::norm(frame.cr, cr, cv::NORM_INF), 1);
      }
    }
  }
}

TEST(V4l2Luma, GreyAndNv12AreViewsOfTheDriverBufferWithItsStride) {
  for (std::uint32_t fourcc : {V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_NV12}) {
    FakeV4l2Device::Config config;
    config.formats = {fourcc};
    config.row_padding = 40;
    FakeV4l2Device device(config);
    V4l2Camera camera(options_for(config), device);
    ASSERT_TRUE(device.produce(test_pattern(device.size(), 1)));
    Frame frame;
    ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
    EXPECT_EQ(frame.gray.step[0], device.bytes_per_line());
    EXPECT_FALSE(frame.gray.isContinuous());
    EXPECT_EQ(frame.gray.u, nullptr) << "a copy instead of a view of the mapped buffer";
  }
}

TEST(V4l2Luma, YuyvReusesOneLumaBuffer) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config, PixelFormat::kYuyv), device);
  std::vector<const std::uint8_t*> planes;
  for (int seed = 0; seed < 3; ++seed) {
    ASSERT_TRUE(device.produce(test_pattern(device.size(), seed)));
    Frame frame;
    ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
    planes.push_back(frame.gray.data);
  }
  EXPECT_EQ(planes[0], planes[1]);
  EXPECT_EQ(planes[1], planes[2]);
}

// ---- buffer handling and timing ----------------------------------------------------------

TEST(V4l2Buffers, EveryDequeuedBufferIsRequeuedOnceAtTheNextGrab) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  {
    V4l2Options options = options_for(config);
    options.buffer_count = 3;
    V4l2Camera camera(options, device);
    ASSERT_EQ(camera.negotiated().buffer_count, 3u);
    for (int seed = 0; seed < 10; ++seed) {
      ASSERT_TRUE(device.produce(test_pattern(device.size(), seed)));
      Frame frame;
      ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
    }
  }
  // The initial QBUF of every buffer, then per grab after the first: QBUF of the buffer the
  // previous grab dequeued, then a DQBUF.
  const auto& events = device.events();
  ASSERT_EQ(events.size(), 3u + 10u + 9u);
  for (unsigned index = 0; index < 3; ++index) {
    EXPECT_EQ(events[index].kind, FakeV4l2Device::Event::kQueue);
    EXPECT_EQ(events[index].index, index);
  }
  unsigned held = events[3].index;
  EXPECT_EQ(events[3].kind, FakeV4l2Device::Event::kDequeue);
  for (std::size_t i = 4; i < events.size(); i += 2) {
    EXPECT_EQ(events[i].kind, FakeV4l2Device::Event::kQueue);
    EXPECT_EQ(events[i].index, held) << "event " << i;
    EXPECT_EQ(events[i + 1].kind, FakeV4l2Device::Event::kDequeue);
    held = events[i + 1].index;
  }
  expect_clean(device);
}

TEST(V4l2Buffers, StalledDeviceTimesOutWithinTheTimeout) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  Frame frame;
  const auto start = Clock::now();
  EXPECT_EQ(camera.grab(frame, 300ms), GrabStatus::kTimeout);
  const auto elapsed = Clock::now() - start;
  EXPECT_GE(elapsed, 295ms);
  EXPECT_LT(elapsed, 300ms + kSlack);
  EXPECT_LE(device.last_poll_timeout_ms(), 300);
  EXPECT_TRUE(device.violations().empty());
}

TEST(V4l2Buffers, SpuriousWakeupIsATimeout) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  device.spurious_wakeup();
  Frame frame;
  const auto start = Clock::now();
  EXPECT_EQ(camera.grab(frame, 200ms), GrabStatus::kTimeout);  // DQBUF said EAGAIN
  EXPECT_LT(Clock::now() - start, kSlack);
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 0)));
  EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
}

TEST(V4l2Buffers, SequenceGapsAreCountedAsDrops) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Options options = options_for(config);
  options.buffer_count = 2;
  V4l2Camera camera(options, device);
  Frame frame;
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 0)));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  EXPECT_EQ(frame.sequence, 0u);

  device.skip_frames(3);  // the sensor lost three
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 1)));
  // One buffer is held by the caller and one is now done: the next capture finds none.
  EXPECT_FALSE(device.produce(test_pattern(device.size(), 2)));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  EXPECT_EQ(frame.sequence, 4u);
  EXPECT_EQ(camera.counters().dropped, 3u);

  ASSERT_TRUE(device.produce(test_pattern(device.size(), 3)));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  EXPECT_EQ(frame.sequence, 6u);
  EXPECT_EQ(camera.counters().dropped, 4u);
  EXPECT_EQ(camera.counters().delivered, 3u);
}

TEST(V4l2Buffers, CorruptBuffersAreReportedAndTheStreamGoesOn) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  {
    V4l2Camera camera(options_for(config, PixelFormat::kYuyv), device);
    Frame frame;
    ASSERT_TRUE(device.produce_error_frame());
    EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kCorrupt);
    ASSERT_TRUE(device.produce_truncated_frame());
    EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kCorrupt);
    const cv::Mat expected = test_pattern(device.size(), 5);
    ASSERT_TRUE(device.produce(expected));
    ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
    EXPECT_EQ(cv::norm(frame.gray, expected, cv::NORM_INF), 0);
    EXPECT_EQ(frame.sequence, 2u);  // the corrupt frames are lost frames
    EXPECT_EQ(camera.counters().corrupt, 2u);
    EXPECT_EQ(camera.counters().dropped, 0u);
  }
  expect_clean(device);  // the corrupt buffers went back to the driver exactly once
}

TEST(V4l2Buffers, BufferThatIsNotAJpegIsCorrupt) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_MJPEG};
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  Frame frame;
  ASSERT_TRUE(device.produce_truncated_frame());  // a fresh buffer: zeros, no JPEG header
  EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kCorrupt);
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 0)));
  EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
}

TEST(V4l2Buffers, MonotonicDriverTimestampsAreUsed) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  Frame frame;
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 0)));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  EXPECT_EQ(frame.capture_time_ns, device.last_timestamp_ns());
  EXPECT_EQ(frame.media_time_s, 0.0);
  std::this_thread::sleep_for(20ms);
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 1)));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  EXPECT_GE(frame.media_time_s, 0.019);
}

/// Grabs one frame from a device made with `config` and checks that it is stamped with the
/// dequeue time (between the times read before and after the grab), not the driver's.
void expect_dequeue_time(const FakeV4l2Device::Config& config) {
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  Frame frame;
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 0)));
  const std::int64_t before = monotonic_ns();
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  const std::int64_t after = monotonic_ns();
  EXPECT_GE(frame.capture_time_ns, before);
  EXPECT_LE(frame.capture_time_ns, after);
  EXPECT_EQ(frame.media_time_s, 0.0);
}

TEST(V4l2Buffers, OtherTimestampsAreReplacedByTheDequeueTime) {
  FakeV4l2Device::Config config;
  config.monotonic_timestamps = false;
  expect_dequeue_time(config);
}

// Found by fuzz_v4l2: seconds of INT64_MIN overflowed the conversion to nanoseconds. A
// timestamp that cannot be a past CLOCK_MONOTONIC time gives way to the dequeue time.
TEST(V4l2Buffers, ImpossibleMonotonicTimestampsAreReplacedByTheDequeueTime) {
  constexpr std::int64_t kMin = std::numeric_limits<std::int64_t>::min();
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  const timeval broken[] = {{kMin, 0}, {kMax, 999'999}, {-1, 0}, {0, -1}, {0, 1'000'000}, {kMin, kMin},
                            {monotonic_ns() / 1'000'000'000 + 3600, 0}};
  for (const timeval& timestamp : broken) {
    SCOPED_TRACE(std::to_string(timestamp.tv_sec) + " s " + std::to_string(timestamp.tv_usec) + " us");
    FakeV4l2Device::Config config;
    config.broken_timestamp = timestamp;
    expect_dequeue_time(config);
  }
}

// ---- disconnects and lifetime ------------------------------------------------------------

TEST(V4l2Disconnect, UnplugWhileHoldingABufferReleasesEverything) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  Frame frame;
  ASSERT_TRUE(device.produce(test_pattern(device.size(), 0)));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  device.unplug();
  EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kDisconnected);  // QBUF says ENODEV
  EXPECT_FALSE(camera.connected());
  EXPECT_EQ(camera.counters().disconnects, 1u);
  expect_clean(device);
}

TEST(V4l2Disconnect, UnplugWhileWaitingReleasesEverything) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  Frame frame;
  ASSERT_EQ(camera.grab(frame, 10ms), GrabStatus::kTimeout);  // holds no buffer now
  device.unplug();
  EXPECT_EQ(camera.grab(frame, 100ms), GrabStatus::kDisconnected);  // poll says POLLERR
  EXPECT_FALSE(camera.connected());
  expect_clean(device);
}

TEST(V4l2Disconnect, FramesResumeWhenTheDeviceComesBack) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_GREY};
  FakeV4l2Device device(config);
  V4l2Camera camera(options_for(config), device);
  Frame frame;
  for (int seed = 0; seed < 2; ++seed) {
    ASSERT_TRUE(device.produce(test_pattern(device.size(), seed)));
    ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  }
  device.unplug();
  ASSERT_EQ(camera.grab(frame, 20ms), GrabStatus::kDisconnected);

  // While the device is away every grab reports it (and keeps trying to reopen it).
  for (int attempt = 0; attempt < 5; ++attempt) EXPECT_EQ(camera.grab(frame, 20ms), GrabStatus::kDisconnected);
  EXPECT_NE(camera.reconnect_error().find(config.path), std::string::npos) << camera.reconnect_error();
  EXPECT_EQ(device.open_fd_count(), 0u);

  ASSERT_NO_FATAL_FAILURE(replug_and_reopen(device, camera));
  EXPECT_EQ(camera.counters().reconnects, 1u);

  const cv::Mat expected = test_pattern(device.size(), 9);
  ASSERT_TRUE(device.produce(expected));
  ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
  EXPECT_EQ(cv::norm(frame.gray, expected, cv::NORM_INF), 0);
  EXPECT_EQ(frame.sequence, 2u);  // keeps counting across the reconnect
  EXPECT_EQ(device.open_fd_count(), 1u);
  EXPECT_TRUE(device.violations().empty());
}

TEST(V4l2Disconnect, BackOffNeverBlocksLongerThanTheTimeout) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Options options = options_for(config);
  options.reconnect_initial = 2000ms;  // blocking until the next attempt would show
  options.reconnect_max = 8000ms;
  V4l2Camera camera(options, device);
  device.unplug();
  Frame frame;
  ASSERT_EQ(camera.grab(frame, 10ms), GrabStatus::kDisconnected);
  for (int attempt = 0; attempt < 3; ++attempt) {
    const auto start = Clock::now();
    EXPECT_EQ(camera.grab(frame, 10ms), GrabStatus::kDisconnected);
    const auto elapsed = Clock::now() - start;
    EXPECT_GE(elapsed, 10ms) << "returned early: a caller looping on grab() would spin";
    EXPECT_LT(elapsed, 10ms + kSlack);
  }
  device.replug();
  // The next attempt is two seconds after the unplug: not yet.
  EXPECT_EQ(camera.grab(frame, 10ms), GrabStatus::kDisconnected);
  EXPECT_EQ(device.open_fd_count(), 0u);
}

TEST(V4l2Disconnect, ReopenAttemptsBackOffExponentially) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  V4l2Options options = options_for(config);
  options.reconnect_initial = 20ms;
  options.reconnect_max = 80ms;
  V4l2Camera camera(options, device);
  device.unplug();
  const std::size_t opens_before = device.open_count();
  Frame frame;
  // Attempts 20, 60, 140, 220, 300 ms after the unplug: five in 300 ms, where a fixed
  // 20 ms delay would make fifteen.
  const auto end = Clock::now() + 310ms;
  while (Clock::now() < end) EXPECT_EQ(camera.grab(frame, 10ms), GrabStatus::kDisconnected);
  const std::size_t attempts = device.open_count() - opens_before;
  EXPECT_GE(attempts, 3u);
  EXPECT_LE(attempts, 5u);
}

TEST(V4l2Lifetime, DestructorStopsAndReleasesEverything) {
  FakeV4l2Device::Config config;
  FakeV4l2Device device(config);
  {
    V4l2Camera camera(options_for(config), device);
    ASSERT_TRUE(device.produce(test_pattern(device.size(), 0)));
    Frame frame;
    ASSERT_EQ(camera.grab(frame, 100ms), GrabStatus::kFrame);
    EXPECT_EQ(device.open_fd_count(), 1u);
    EXPECT_EQ(device.mapping_count(), camera.negotiated().buffer_count);
  }
  EXPECT_FALSE(device.streaming());
  expect_clean(device);
}

TEST(V4l2Lifetime, FailedOpenReleasesWhatItTook) {
  FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_RGB24};
  FakeV4l2Device device(config);
  EXPECT_THROW(V4l2Camera(options_for(config), device), SourceError);
  expect_clean(device);
}

// The Cr of a 4:2:0 picture in each layout cameras deliver (V4L2's NV12, libcamera's four):
// a 10 x 6 picture, its chroma planes padded past their width, every Cb and Cr sample a
// value of its own.
struct Picture420 {
  static constexpr int kWidth = 10, kHeight = 6, kLumaStride = 16;
  Chroma420 layout;
  std::vector<std::uint8_t> bytes;  // luma, then the chroma plane(s)
  std::size_t stride = chroma_stride(layout, kLumaStride);

  static std::uint8_t cr(int x, int y) { return static_cast<std::uint8_t>(100 + 10 * y + x); }
  static std::uint8_t cb(int x, int y) { return static_cast<std::uint8_t>(30 + 10 * y + x); }

  explicit Picture420(Chroma420 which) : layout(which) {
    const std::size_t luma = std::size_t{kLumaStride} * kHeight, plane = stride * (kHeight / 2);
    const bool pairs = layout == Chroma420::kPairs || layout == Chroma420::kPairsCrFirst;
    bytes.assign(luma + (pairs ? plane : 2 * plane), 0xee);  // padding reads 0xee
    for (int y = 0; y < kHeight / 2; ++y)
      for (int x = 0; x < kWidth / 2; ++x) {
        const std::size_t row = luma + static_cast<std::size_t>(y) * stride;
        switch (layout) {
          case Chroma420::kPlanes: bytes[row + x] = cb(x, y), bytes[row + plane + x] = cr(x, y); break;
          case Chroma420::kPlanesCrFirst: bytes[row + x] = cr(x, y), bytes[row + plane + x] = cb(x, y); break;
          case Chroma420::kPairs: bytes[row + 2 * x] = cb(x, y), bytes[row + 2 * x + 1] = cr(x, y); break;
          case Chroma420::kPairsCrFirst: bytes[row + 2 * x] = cr(x, y), bytes[row + 2 * x + 1] = cb(x, y); break;
        }
      }
  }
  /// The chroma plane that holds Cr, as a camera driver finds it.
  const std::uint8_t* cr_plane() const {
    return bytes.data() + std::size_t{kLumaStride} * kHeight +
           static_cast<std::size_t>(cr_plane_index(layout)) * stride * (kHeight / 2);
  }
};

TEST(Chroma420, EveryLayoutGivesTheCrSamplesAtHalfTheSize) {
  for (const Chroma420 layout :
       {Chroma420::kPlanes, Chroma420::kPlanesCrFirst, Chroma420::kPairs, Chroma420::kPairsCrFirst}) {
    SCOPED_TRACE(static_cast<int>(layout));
    const Picture420 picture(layout);
    cv::Mat gathered;
    const cv::Mat cr =
        cr_of_420(layout, picture.cr_plane(), picture.stride, Picture420::kWidth, Picture420::kHeight, gathered);
    ASSERT_EQ(cr.size(), cv::Size(5, 3));
    ASSERT_EQ(cr.type(), CV_8UC1);
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 5; ++x) EXPECT_EQ(cr.at<std::uint8_t>(y, x), Picture420::cr(x, y)) << x << ", " << y;
    EXPECT_LE(chroma_plane_bytes(layout, Picture420::kWidth, Picture420::kHeight, picture.stride),
              picture.bytes.size() - static_cast<std::size_t>(picture.cr_plane() - picture.bytes.data()));
  }
}

TEST(Chroma420, PlanesAreWrappedAndPairsGatheredWithoutAllocatingPerFrame) {
  const Picture420 planar(Chroma420::kPlanes);
  cv::Mat gathered;
  const cv::Mat view = cr_of_420(Chroma420::kPlanes, planar.cr_plane(), planar.stride, 10, 6, gathered);
  EXPECT_EQ(view.data, planar.cr_plane());
  EXPECT_EQ(view.step[0], planar.stride);
  EXPECT_TRUE(gathered.empty());

  const Picture420 pairs(Chroma420::kPairs);
  gathered.create(3, 5, CV_8UC1);  // as a camera does once per stream
  const std::uint8_t* own = gathered.data;
  lipdrive::test::count_allocations_on_this_thread(true);
  const long before = lipdrive::test::allocation_count();
  const cv::Mat cr = cr_of_420(Chroma420::kPairs, pairs.cr_plane(), pairs.stride, 10, 6, gathered);
  const long allocations = lipdrive::test::allocation_count() - before;
  lipdrive::test::count_allocations_on_this_thread(false);
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(cr.data, own);
}

TEST(Chroma420, ChromaStridesFollowTheLuma) {
  EXPECT_EQ(chroma_stride(Chroma420::kPlanes, 640), 320u);
  EXPECT_EQ(chroma_stride(Chroma420::kPlanesCrFirst, 640), 320u);
  EXPECT_EQ(chroma_stride(Chroma420::kPairs, 640), 640u);
  EXPECT_EQ(chroma_stride(Chroma420::kPairsCrFirst, 640), 640u);
  EXPECT_EQ(cr_plane_index(Chroma420::kPlanes), 1);
  EXPECT_EQ(cr_plane_index(Chroma420::kPlanesCrFirst), 0);
  // The last row needs only its samples, not the padding after them.
  EXPECT_EQ(chroma_plane_bytes(Chroma420::kPairs, 640, 480, 704), 704u * 239 + 640);
  EXPECT_EQ(chroma_plane_bytes(Chroma420::kPlanes, 640, 480, 352), 352u * 239 + 320);
  EXPECT_EQ(chroma_plane_bytes(Chroma420::kPlanes, 1, 480, 352), 0u);
}

TEST(Chroma420, CrIsFoundInItsOwnBufferPlaneOrAfterTheLumaInASingleOne) {
  constexpr std::size_t kStride = 704;  // 640 × 480 with padded rows
  constexpr std::size_t kLuma = kStride * 480, kQuarter = kStride / 2 * 240, kPairs = kStride * 240;
  // libcamera's buffers: a plane per colour plane, here on one dmabuf at increasing offsets.
  const std::array<BufferBytes, 3> three{{{0, 0, kLuma}, {1, kLuma, kQuarter}, {2, kLuma + kQuarter, kQuarter}}};
  const auto cr = locate_cr(Chroma420::kPlanes, three, kStride, 640, 480);
  ASSERT_TRUE(cr.has_value());
  EXPECT_EQ(cr->plane, 2u);
  EXPECT_EQ(cr->offset, kLuma + kQuarter);
  const auto crfirst = locate_cr(Chroma420::kPlanesCrFirst, three, kStride, 640, 480);
  ASSERT_TRUE(crfirst.has_value());
  EXPECT_EQ(crfirst->plane, 1u);
  // One plane holding everything, at an offset in its dmabuf.
  const std::array<BufferBytes, 1> one{{{0, 4096, kLuma + kPairs}}};
  const auto pairs = locate_cr(Chroma420::kPairs, one, kStride, 640, 480);
  ASSERT_TRUE(pairs.has_value());
  EXPECT_EQ(pairs->offset, 4096 + kLuma);
  EXPECT_EQ(pairs->length, kPairs);
  const std::array<BufferBytes, 1> planar{{{0, 0, kLuma + 2 * kQuarter}}};
  const auto second = locate_cr(Chroma420::kPlanes, planar, kStride, 640, 480);
  ASSERT_TRUE(second.has_value());
  EXPECT_EQ(second->offset, kLuma + kQuarter);  // after the Cb plane
  // Too short by a byte, or planes that do not match the layout: no colour.
  const std::array<BufferBytes, 1> short_one{{{0, 0, kLuma + kPairs - (kStride - 640) - 1}}};
  EXPECT_FALSE(locate_cr(Chroma420::kPairs, short_one, kStride, 640, 480).has_value());
  const std::array<BufferBytes, 1> just{{{0, 0, kLuma + kPairs - (kStride - 640)}}};
  EXPECT_TRUE(locate_cr(Chroma420::kPairs, just, kStride, 640, 480).has_value());
  const std::array<BufferBytes, 2> two{{{0, 0, kLuma}, {1, kLuma, kQuarter}}};
  EXPECT_FALSE(locate_cr(Chroma420::kPlanes, two, kStride, 640, 480).has_value());
  EXPECT_FALSE(locate_cr(Chroma420::kPairs, std::span<const BufferBytes>(), kStride, 640, 480).has_value());
}

// Through the kernel's own calls: a node that is not there is waited for, named; one that is
// no video device (/dev/null) is an error naming it.
TEST(V4l2RealSystemCalls, AMissingDeviceIsWaitedForAndANonCameraThrows) {
  V4l2Options options;
  options.device = "/dev/video-does-not-exist";
  V4l2Camera absent(options);
  EXPECT_FALSE(absent.connected());
  EXPECT_NE(absent.reconnect_error().find("/dev/video-does-not-exist"), std::string::npos) << absent.reconnect_error();
  options.device = "/dev/null";
  try {
    V4l2Camera camera(options);
    FAIL() << "opened /dev/null as a camera";
  } catch (const SourceError& error) {
    EXPECT_NE(std::string(error.what()).find("/dev/null"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace lipdrive
