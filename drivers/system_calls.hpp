// The seam between the drivers and the kernel: every system call a driver makes on a
// device goes through a SystemCalls, so tests run the real driver code against a fake
// device (tests/fake_v4l2_device.hpp) instead of hardware.
//
// The signatures and the error convention are the POSIX ones: a failing call returns -1
// (MAP_FAILED for mmap) and leaves the error code in errno, so the forwarding to the OS is
// trivial and a fake reproduces exactly what the kernel would report.
#pragma once

#include <poll.h>
#include <sys/types.h>

#include <cstddef>

namespace lipdrive {

class SystemCalls {
 public:
  virtual ~SystemCalls() = default;
  virtual int open(const char* path, int flags) = 0;
  virtual int close(int fd) = 0;
  virtual int ioctl(int fd, unsigned long request, void* argument) = 0;
  virtual void* mmap(void* address, std::size_t length, int protection, int flags, int fd, off_t offset) = 0;
  virtual int munmap(void* address, std::size_t length) = 0;
  virtual int poll(pollfd* fds, nfds_t count, int timeout_ms) = 0;
};

/// The operating system's calls. ioctl restarts on EINTR (a signal arriving mid-call is
/// not a device error); poll does not, so that the caller keeps control of its deadline.
SystemCalls& real_system_calls();

}  // namespace lipdrive
