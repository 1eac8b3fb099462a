// Test-side serial peers: socat pty pairs (a null-modem cable between two serial devices),
// a reader for the far end, and a decoder of framed frames written from
// docs/serial-protocol.md.
#pragma once

#include "drivers/serial_protocol.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace lipdrive::test {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

// Calls `step` until it returns true or `timeout` passes; false on timeout.
inline bool eventually(const std::function<bool()>& step, std::chrono::milliseconds timeout = 3s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (step()) return true;
    std::this_thread::sleep_for(2ms);
  }
  return step();
}

// ---- test-side peers ------------------------------------------------------------------

class TempDir {
 public:
  TempDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "lipdrive-test-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// socat joining two ptys; `a` and `b` are the links to their slave ends.
class PtyPair {
 public:
  explicit PtyPair(const std::filesystem::path& dir) : a(dir / "a"), b(dir / "b") {
    std::filesystem::create_directories(dir);
    const std::string log = (dir / "socat.log").string();
    const std::string left = "pty,raw,echo=0,link=" + a.string();
    const std::string right = "pty,raw,echo=0,link=" + b.string();
    const char* argv[] = {"socat", "-d", "-d", left.c_str(), right.c_str(), nullptr};
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    const int error = posix_spawnp(&pid_, "socat", &actions, nullptr, const_cast<char**>(argv), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (error != 0) throw std::runtime_error("cannot start socat");
    if (!eventually([&] { return std::filesystem::exists(a) && std::filesystem::exists(b); }))
      throw std::runtime_error("socat made no pty links");
  }
  ~PtyPair() { stop(); }
  PtyPair(const PtyPair&) = delete;
  PtyPair& operator=(const PtyPair&) = delete;

  /// Ends socat (SIGTERM: it removes its links) and reaps it: the ptys close.
  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

  const std::filesystem::path a, b;

 private:
  pid_t pid_ = -1;
};

// The far end of a pty pair: accumulates whatever arrives.
class PtyReader {
 public:
  explicit PtyReader(const std::filesystem::path& device)
      : fd_(::open(device.c_str(), O_RDONLY | O_NOCTTY | O_NONBLOCK | O_CLOEXEC)) {
    if (fd_ < 0) throw std::runtime_error("cannot open " + device.string());
    termios options{};
    ::tcgetattr(fd_, &options);
    ::cfmakeraw(&options);
    ::tcsetattr(fd_, TCSANOW, &options);
  }
  ~PtyReader() { ::close(fd_); }
  PtyReader(const PtyReader&) = delete;
  PtyReader& operator=(const PtyReader&) = delete;

  const Bytes& read_available() {
    std::uint8_t chunk[4096];
    ssize_t count;
    while ((count = ::read(fd_, chunk, sizeof chunk)) > 0) bytes_.insert(bytes_.end(), chunk, chunk + count);
    return bytes_;
  }

 private:
  int fd_;
  Bytes bytes_;
};

// ---- decoders, written from docs/serial-protocol.md -----------------------------------

struct DecodedFrame {
  std::uint16_t sequence;
  std::uint32_t time_us;
  std::uint16_t status;
  std::vector<std::int16_t> values;
};

struct FrameStream {
  std::vector<DecodedFrame> frames;
  std::size_t skipped_bytes = 0;  // bytes that were not part of a valid frame
};

inline std::uint16_t le16(const std::uint8_t* at) { return static_cast<std::uint16_t>(at[0] | at[1] << 8); }

inline FrameStream decode_frames(const Bytes& bytes) {
  FrameStream stream;
  std::size_t at = 0;
  while (at + 2 <= bytes.size()) {
    const std::size_t length = bytes[at + 1];
    const bool plausible = bytes[at] == serial_protocol::kFrameStart && length >= 8 && length % 2 == 0;
    if (plausible && at + 2 + length + 2 > bytes.size()) break;  // incomplete: wait for more
    const auto* frame = bytes.data() + at;
    if (!plausible || serial_protocol::crc16_modbus({frame, 2 + length}) != le16(frame + 2 + length)) {
      ++stream.skipped_bytes;
      ++at;
      continue;
    }
    DecodedFrame decoded{
        le16(frame + 2), static_cast<std::uint32_t>(le16(frame + 4) | le16(frame + 6) << 16), le16(frame + 8), {}};
    for (std::size_t i = 10; i < 2 + length; i += 2)
      decoded.values.push_back(static_cast<std::int16_t>(le16(frame + i)));
    stream.frames.push_back(decoded);
    at += 2 + length + 2;
  }
  return stream;
}

}  // namespace lipdrive::test
