// The libcamera source on a machine without cameras: construction fails cleanly and fast,
// and libcamera's process-wide state (one CameraManager) is torn down and rebuilt each time.
#include "drivers/libcamera_camera.hpp"

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
