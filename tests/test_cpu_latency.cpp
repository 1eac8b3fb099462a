// The CPU wake-up latency request (drivers/cpu_latency.hpp): against a FIFO that stands in for
// the kernel's PM QoS file, and against the kernel's own file where this process may write it.
#include "drivers/cpu_latency.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <filesystem>

namespace lipdrive {
namespace {

namespace fs = std::filesystem;

// The kernel takes the request as a binary 32-bit value and keeps it while the file is open:
// the FIFO's reader sees exactly that value, then no end of file until the request is released.
TEST(CpuLatencyRequest, WritesTheValueAndHoldsTheFileUntilReleased) {
  const fs::path fifo = fs::temp_directory_path() / ("lipdrive_test_cpu_latency_" + std::to_string(::getpid()));
  fs::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const int reader = ::open(fifo.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  ASSERT_GE(reader, 0);
  CpuLatencyRequest request;
  EXPECT_FALSE(request.held());
  ASSERT_EQ(request.request(42, fifo), "");
  EXPECT_TRUE(request.held());
  std::int32_t value = 0;
  ASSERT_EQ(::read(reader, &value, sizeof value), static_cast<ssize_t>(sizeof value));
  EXPECT_EQ(value, 42);
  std::uint8_t byte = 0;
  EXPECT_EQ(::read(reader, &byte, 1), -1) << "nothing more, and the writer still holds the file";
  EXPECT_EQ(errno, EAGAIN);
  request.release();
  EXPECT_FALSE(request.held());
  EXPECT_EQ(::read(reader, &byte, 1), 0) << "released: the file is closed";
  ::close(reader);
  fs::remove(fifo);
}

TEST(CpuLatencyRequest, AFileThatCannotBeOpenedIsNamedAndNothingIsHeld) {
  const fs::path missing = fs::temp_directory_path() / "lipdrive_no_such_dir" / "cpu_dma_latency";
  CpuLatencyRequest request;
  const std::string why = request.request(0, missing);
  EXPECT_NE(why.find(missing.string()), std::string::npos) << why;
  EXPECT_NE(why.find("No such file"), std::string::npos) << why;
  EXPECT_FALSE(request.held());
}

// The kernel's own interface: while held, the system's target is at most the request; after
// release it is what it was.
TEST(CpuLatencyRequest, TheKernelsTargetFollowsTheRequest) {
  const std::optional<std::int32_t> before = CpuLatencyRequest::current_target();
  if (!before || ::access(CpuLatencyRequest::kDevice, W_OK) != 0)
    GTEST_SKIP() << CpuLatencyRequest::kDevice << " cannot be read and written here";
  CpuLatencyRequest request;
  ASSERT_EQ(request.request(3), "");
  const std::optional<std::int32_t> held = CpuLatencyRequest::current_target();
  ASSERT_TRUE(held);
  EXPECT_LE(*held, 3);
  request.release();
  EXPECT_EQ(CpuLatencyRequest::current_target(), before);
}

}  // namespace
}  // namespace lipdrive
