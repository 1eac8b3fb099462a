// V4L2 buffer metadata: what the driver reports about the format (G_FMT/S_FMT: size, bytes
// per line, image size) and about every dequeued buffer (index, bytesused, flags, field,
// timestamp, sequence) comes from a kernel driver we do not control. The fake device of the
// tests answers as a camera would, then the fuzzer's bytes overwrite those fields; the
// camera must reject or survive whatever it is told, never read outside its buffers.
#include "drivers/v4l2_camera.hpp"
#include "fake_v4l2_device.hpp"

#include <fuzzer/FuzzedDataProvider.h>
#include <spdlog/spdlog.h>

#include <linux/videodev2.h>

namespace {

using namespace lipdrive;

/// The fake device, with the fuzzer rewriting what it answers.
class LyingDevice final : public SystemCalls {
 public:
  LyingDevice(testing::FakeV4l2Device& device, FuzzedDataProvider& lies) : device_(device), lies_(lies) {}
  int open(const char* path, int flags) override { return device_.open(path, flags); }
  int close(int fd) override { return device_.close(fd); }
  void* mmap(void* address, std::size_t length, int protection, int flags, int fd, off_t offset) override {
    return device_.mmap(address, length, protection, flags, fd, offset);
  }
  int munmap(void* address, std::size_t length) override { return device_.munmap(address, length); }
  int poll(pollfd* fds, nfds_t count, int timeout_ms) override { return device_.poll(fds, count, timeout_ms); }
  int ioctl(int fd, unsigned long request, void* argument) override {
    const int result = device_.ioctl(fd, request, argument);
    if (result != 0 || !lies_.ConsumeBool()) return result;
    if (request == VIDIOC_G_FMT || request == VIDIOC_S_FMT || request == VIDIOC_TRY_FMT) {
      v4l2_pix_format& pix = static_cast<v4l2_format*>(argument)->fmt.pix;
      pix.width = lies_.ConsumeIntegralInRange<std::uint32_t>(0, 4096);
      pix.height = lies_.ConsumeIntegralInRange<std::uint32_t>(0, 4096);
      pix.bytesperline = lies_.ConsumeIntegral<std::uint32_t>();
      pix.sizeimage = lies_.ConsumeIntegral<std::uint32_t>();
      if (lies_.ConsumeBool()) pix.pixelformat = lies_.ConsumeIntegral<std::uint32_t>();
    } else if (request == VIDIOC_DQBUF) {
      v4l2_buffer& buffer = *static_cast<v4l2_buffer*>(argument);
      buffer.index = lies_.ConsumeIntegralInRange<std::uint32_t>(0, 9);
      buffer.bytesused = lies_.ConsumeIntegral<std::uint32_t>();
      buffer.flags = lies_.ConsumeIntegral<std::uint32_t>();
      buffer.field = lies_.ConsumeIntegral<std::uint32_t>();
      buffer.sequence = lies_.ConsumeIntegral<std::uint32_t>();
      buffer.timestamp.tv_sec = lies_.ConsumeIntegral<std::int64_t>();
      buffer.timestamp.tv_usec = lies_.ConsumeIntegral<std::int64_t>();
    } else if (request == VIDIOC_REQBUFS) {
      static_cast<v4l2_requestbuffers*>(argument)->count = lies_.ConsumeIntegralInRange<std::uint32_t>(0, 40);
    } else if (request == VIDIOC_QUERYBUF) {
      v4l2_buffer& buffer = *static_cast<v4l2_buffer*>(argument);
      buffer.length = lies_.ConsumeIntegral<std::uint32_t>();
    }
    return result;
  }

 private:
  testing::FakeV4l2Device& device_;
  FuzzedDataProvider& lies_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const bool quiet = (spdlog::set_level(spdlog::level::off), true);
  (void)quiet;
  FuzzedDataProvider lies(data, size);
  testing::FakeV4l2Device::Config config;
  config.formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY, V4L2_PIX_FMT_NV12};
  config.sizes = {{64, 48}, {32, 24}};
  testing::FakeV4l2Device device(config);
  LyingDevice lying(device, lies);
  V4l2Options options;
  options.device = config.path;
  const PixelFormat formats[] = {PixelFormat::kAuto, PixelFormat::kYuyv, PixelFormat::kGrey, PixelFormat::kNv12};
  options.format = formats[lies.ConsumeIntegralInRange<int>(0, 3)];
  try {
    V4l2Camera camera(options, lying);
    Frame frame;
    for (int i = 0; i < 4 && lies.remaining_bytes() > 0; ++i) {
      device.produce(testing::test_pattern(device.size(), i));
      if (camera.grab(frame, std::chrono::milliseconds(0)) == GrabStatus::kFrame) {
        // Every pixel the camera hands out must be readable.
        volatile unsigned sum = 0;
        for (int y = 0; y < frame.gray.rows; ++y)
          for (int x = 0; x < frame.gray.cols; ++x) sum = sum + frame.gray.at<unsigned char>(y, x);
      }
    }
  } catch (const SourceError&) {
  }
  return 0;
}
