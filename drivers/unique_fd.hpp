// An owned file descriptor: closed exactly once, when its owner lets go of it.
//
// The descriptor is closed through the SystemCalls it was opened with, so a driver tested
// against a fake device (drivers/system_calls.hpp) closes the fake's descriptors, not the
// operating system's.
#pragma once

#include "drivers/system_calls.hpp"

#include <utility>

namespace lipdrive {

class UniqueFd {
 public:
  UniqueFd() = default;
  /// Takes ownership of `fd` (-1: nothing).
  explicit UniqueFd(int fd, SystemCalls& system = real_system_calls()) : fd_(fd), system_(&system) {}
  UniqueFd(UniqueFd&& other) noexcept : fd_(std::exchange(other.fd_, -1)), system_(other.system_) {}
  UniqueFd& operator=(UniqueFd&& other) noexcept {
    if (this != &other) {
      reset();
      fd_ = std::exchange(other.fd_, -1);
      system_ = other.system_;
    }
    return *this;
  }
  ~UniqueFd() { reset(); }
  UniqueFd(const UniqueFd&) = delete;
  UniqueFd& operator=(const UniqueFd&) = delete;

  int get() const { return fd_; }
  bool valid() const { return fd_ != -1; }
  /// Closes the descriptor now.
  void reset() {
    if (fd_ != -1) system_->close(std::exchange(fd_, -1));
  }

 private:
  int fd_ = -1;
  SystemCalls* system_ = &real_system_calls();
};

}  // namespace lipdrive
