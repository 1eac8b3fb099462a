#include "drivers/system_calls.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>

namespace lipdrive {
namespace {

class OperatingSystemCalls final : public SystemCalls {
 public:
  int open(const char* path, int flags) override { return ::open(path, flags); }
  int close(int fd) override { return ::close(fd); }
  int ioctl(int fd, unsigned long request, void* argument) override {
    int result;
    do {
      result = ::ioctl(fd, request, argument);
    } while (result == -1 && errno == EINTR);
    return result;
  }
  void* mmap(void* address, std::size_t length, int protection, int flags, int fd, off_t offset) override {
    return ::mmap(address, length, protection, flags, fd, offset);
  }
  int munmap(void* address, std::size_t length) override { return ::munmap(address, length); }
  int poll(pollfd* fds, nfds_t count, int timeout_ms) override { return ::poll(fds, count, timeout_ms); }
};

}  // namespace

SystemCalls& real_system_calls() {
  // Stateless, so one shared instance is no hidden state.
  static OperatingSystemCalls calls;
  return calls;
}

}  // namespace lipdrive
