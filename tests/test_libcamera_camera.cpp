// The libcamera source on a machine without cameras: construction fails cleanly and fast, or
// waits for a camera when asked to, and libcamera's process-wide state (one CameraManager) is
// torn down and rebuilt each time.
#include "drivers/libcamera_camera.hpp"
#include "tests/captured_log.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

namespace lipdrive {
namespace {

using Clock = std::chrono::steady_clock;

TEST(LibcameraCamera, NoCamerasIsACleanSourceError) {
  // Twice and more: a manager left running, or not destroyed, would make the next
  // construction abort (libcamera allows one CameraManager per process) or hang.
  for (int attempt = 0; attempt < 3; ++attempt) {
    const Clock::time_point start = Clock::now();
    try {
      LibcameraCamera camera(LibcameraOptions{});
      ADD_FAILURE() << "found a camera: " << camera.describe();
    } catch (const SourceError& error) {
      EXPECT_EQ(std::string(error.what()), "libcamera: no cameras found") << "attempt " << attempt;
    }
    EXPECT_LT(Clock::now() - start, std::chrono::seconds(5)) << "attempt " << attempt;
  }
}

TEST(LibcameraCamera, NoCamerasIsACleanSourceErrorWhateverTheOptions) {
  LibcameraOptions options;
  options.camera_id = "/base/soc/i2c0mux/i2c@1/imx219@10";
  options.width = 640;
  options.height = 480;
  options.frame_rate = 30;
  try {
    LibcameraCamera camera(options);
    ADD_FAILURE() << "found a camera: " << camera.describe();
  } catch (const SourceError& error) {
    EXPECT_EQ(std::string(error.what()), "libcamera: no cameras found");
  }
}

// The daemon started at boot before the CSI camera and its ISP were enumerated: the camera is
// away, as after an unplug, and every grab says so within its timeout while it is looked for.
TEST(LibcameraCamera, ACameraNotThereIsWaitedForWhenAsked) {
  for (const std::string id : {"", "/base/soc/i2c0mux/i2c@1/imx219@10"}) {
    LibcameraOptions options;
    options.camera_id = id;
    options.frame_rate = 30;
    options.wait_when_absent = true;
    const testing::CapturedLog log;
    LibcameraCamera camera(options);
    EXPECT_EQ(camera.describe(), id.empty() ? "libcamera:(first camera)" : "libcamera:" + id);
    EXPECT_DOUBLE_EQ(camera.frame_rate(), 30) << "the rate asked for until the camera opens";
    Frame frame;
    for (int attempt = 0; attempt < 4; ++attempt) {
      const Clock::time_point start = Clock::now();
      EXPECT_EQ(camera.grab(frame, std::chrono::milliseconds(200)), GrabStatus::kDisconnected) << attempt;
      // Generous for sanitizer builds: the back-off never holds a grab past its timeout.
      EXPECT_LT(Clock::now() - start, std::chrono::seconds(2)) << attempt;
    }
    EXPECT_EQ(log.messages(spdlog::level::warn),
              std::vector<std::string>{"libcamera: no cameras found; waiting for it"});
  }
}

TEST(LibcameraCamera, SourcesOnSeveralThreadsShareTheOneCameraManager) {
  // A front and a side camera open concurrently; a second CameraManager alive at the same
  // time would abort the process.
  std::atomic<int> clean_errors{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t)
    threads.emplace_back([&] {
      for (int attempt = 0; attempt < 5; ++attempt) {
        try {
          LibcameraCamera camera(LibcameraOptions{});
        } catch (const SourceError& error) {
          clean_errors += std::string(error.what()) == "libcamera: no cameras found";
        }
      }
    });
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(clean_errors.load(), 20);
}

}  // namespace
}  // namespace lipdrive
