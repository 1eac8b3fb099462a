// A `lipdrive run` child process for the daemon tests.
#pragma once

#include "build_paths.hpp"
#include <gtest/gtest.h>

#include <algorithm>
#include <arpa/inet.h>
#include <chrono>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <string>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

extern char** environ;

namespace lipdrive::test {

using namespace std::chrono_literals;

/// A `lipdrive run` child process with stderr in a file.
class DaemonProcess {
 public:
  /// `extra_args` are split at spaces; `environment` entries ("NAME=value") are added to ours.
  DaemonProcess(const std::filesystem::path& config, const std::filesystem::path& log,
                const std::string& extra_args = "", const std::vector<std::string>& environment = {})
      : log_(log) {
    std::vector<std::string> args = {kLipdrive, "run", "--config", config.string()};
    for (std::size_t start = 0; start < extra_args.size();) {
      const std::size_t end = std::min(extra_args.find(' ', start), extra_args.size());
      if (end > start) args.push_back(extra_args.substr(start, end - start));
      start = end + 1;
    }
    std::vector<char*> argv;
    for (auto& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    std::vector<std::string> env_strings(environment);
    for (char** e = environ; *e; ++e) env_strings.emplace_back(*e);
    std::vector<char*> env;
    for (auto& entry : env_strings) env.push_back(entry.data());
    env.push_back(nullptr);
    EXPECT_EQ(posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), env.data()), 0);
    posix_spawn_file_actions_destroy(&actions);
  }
  ~DaemonProcess() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }

  std::string log() const {
    std::ifstream in(log_);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  bool wait_for_log(const std::string& text, std::chrono::seconds limit = 60s) const {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < deadline) {
      if (log().find(text) != std::string::npos) return true;
      std::this_thread::sleep_for(20ms);
    }
    return false;
  }
  void signal(int number) const { ::kill(pid_, number); }
  pid_t pid() const { return pid_; }
  bool running() {
    int status = 0;
    return !exited_ && ::waitpid(pid_, &status, WNOHANG) == 0;
  }
  /// Exit code, or -1 on a signal or when it is still running after `limit`.
  int wait(std::chrono::milliseconds limit) {
    const auto deadline = std::chrono::steady_clock::now() + limit;
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) return -1;
      std::this_thread::sleep_for(5ms);
    }
    exited_ = true;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

 private:
  std::filesystem::path log_;
  pid_t pid_ = -1;
  bool exited_ = false;
};

/// A stand-in for systemd's notification socket; pass environment() to the daemon.
class NotifySocket {
 public:
  explicit NotifySocket(const std::filesystem::path& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un address{};
    address.sun_family = AF_UNIX;
    EXPECT_LT(path.string().size(), sizeof address.sun_path);
    std::strncpy(address.sun_path, path.c_str(), sizeof address.sun_path - 1);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address), 0) << path;
  }
  ~NotifySocket() { ::close(fd_); }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;

  std::string environment() const { return "NOTIFY_SOCKET=" + path_.string(); }
  /// The next message, or "" when none arrives within `timeout`.
  std::string receive(std::chrono::milliseconds timeout) const {
    pollfd readable{fd_, POLLIN, 0};
    if (::poll(&readable, 1, static_cast<int>(timeout.count())) != 1) return {};
    char message[512];
    const ssize_t size = ::recv(fd_, message, sizeof message, 0);
    return {message, static_cast<std::size_t>(size > 0 ? size : 0)};
  }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

/// A loopback port of `type` (SOCK_STREAM, SOCK_DGRAM) nothing uses right now.
inline int free_port(int type = SOCK_STREAM) {
  const int fd = ::socket(AF_INET, type, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
  socklen_t size = sizeof address;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &size);
  ::close(fd);
  return ntohs(address.sin_port);
}

/// A loopback port another program listens on, until release().
class PortInUse {
 public:
  /// A TCP port (listened on), or with SOCK_DGRAM a UDP one, on the loopback interface. The
  /// socket is not inherited by a daemon the test starts.
  explicit PortInUse(int type = SOCK_STREAM) : fd_(::socket(AF_INET, type | SOCK_CLOEXEC, 0)) {
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    if (type == SOCK_STREAM) EXPECT_EQ(::listen(fd_, 1), 0);
    socklen_t size = sizeof address;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&address), &size);
    port_ = ntohs(address.sin_port);
  }
  ~PortInUse() { release(); }
  PortInUse(const PortInUse&) = delete;
  PortInUse& operator=(const PortInUse&) = delete;

  int port() const { return port_; }
  /// Closes the socket: the port is free.
  void release() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
  int port_ = 0;
};

/// The systemd watchdog pings among the messages of a NotifySocket, and the longest gap
/// between two of them.
class WatchdogPings {
 public:
  using Clock = std::chrono::steady_clock;
  /// Counts `message` when it is a ping.
  void see(const std::string& message) {
    if (message.find("WATCHDOG=1") == std::string::npos) return;
    const Clock::time_point now = Clock::now();
    if (count_++ > 0) take_gap(now);
    last_ = now;
  }
  /// The gap from the last ping to now counts too (a daemon that stopped pinging).
  void close() { take_gap(Clock::now()); }
  int count() const { return count_; }
  std::chrono::milliseconds longest_gap() const { return longest_; }

 private:
  void take_gap(Clock::time_point now) {
    longest_ = std::max(longest_, std::chrono::duration_cast<std::chrono::milliseconds>(now - last_));
  }
  Clock::time_point last_{};
  std::chrono::milliseconds longest_{0};
  int count_ = 0;
};

}  // namespace lipdrive::test
