// Take recording: every processed frame as one CSV row (the columns of `lipdrive process`
// plus drive (who drove at that frame: video, voice or fail-safe), capture_time_ns and, when a
// timecode source is configured, the frame's timecode; the take then begins with a comment
// line naming the timecode of its first frame), written by a
// thread of its own so that slow or failing storage never holds up the pipeline or the
// outputs. With a voice input the take's sound goes beside it (NAME.wav, TakeSound).
//
// The processing thread hands results over through a fixed-size single-producer ring; the
// recorder thread formats them and appends complete lines only, one write() per batch, and
// calls fdatasync every flush interval. A crash or a power cut can therefore tear at most
// the last line, and loses at most one flush interval. A write error (ENOSPC, EIO) ends the
// take with a logged error.
#pragma once

#include "core/timecode.hpp"
#include "drivers/unique_fd.hpp"
#include "firmware_app/daemon/frame_result.hpp"
#include "firmware_app/daemon/take_sound.hpp"

#include <fmt/format.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace lipdrive {

/// DIR/NAME.csv, or DIR/take-YYYYmmdd-HHMMSS.csv for the current local time when `name` is
/// empty; -2, -3, ... appended when taken.
std::filesystem::path take_file_name(const std::filesystem::path& dir, const std::string& name = "");

class TakeRecorder : public ResultSink {
 public:
  /// `source`: the source column of every row. `timecode_rate`: the rows carry a timecode
  /// column at this rate. `sound`: the voice input's sound, written beside every take (it
  /// must outlive the recorder).
  TakeRecorder(std::string source, std::chrono::milliseconds flush_interval,
               std::optional<TimecodeRate> timecode_rate = std::nullopt, TakeSound* sound = nullptr);
  ~TakeRecorder() override;
  TakeRecorder(const TakeRecorder&) = delete;
  TakeRecorder& operator=(const TakeRecorder&) = delete;

  /// Starts a take in `file` (its folder is created; an existing file is replaced). Problems
  /// opening it are logged, like write errors, and end the take.
  void start(const std::filesystem::path& file);
  /// Writes the rows handed over so far and closes the take.
  void stop();
  bool recording() const { return active_.load(std::memory_order_acquire); }

  /// Processing thread: queues a row. Never blocks or allocates; a full ring drops the row
  /// (counted and logged when the take closes).
  void push(const FrameResult& result) override;

  /// Why the last take ended early, if it did.
  std::optional<std::string> error() const;

 private:
  static constexpr std::size_t kRingSize = 1024;  // 17 s at 60 fps of storage stalling

  void run();
  void apply_request();
  void open_take(const std::filesystem::path& file);
  void close_take();
  void drain();
  /// The take's first lines; `first`: its first row (nullptr: the take has none).
  void append_header(const FrameResult* first);
  bool write_all(const char* data, std::size_t size);
  /// Ends the take on a write or open error: logged, and error() says it unless another take
  /// was asked for meanwhile.
  void fail(const std::string& message);

  std::string source_;
  std::chrono::milliseconds flush_interval_;
  std::optional<TimecodeRate> timecode_rate_;
  TakeSound* sound_;

  SingleProducerRing<FrameResult, kRingSize> ring_;  // full: rows lost, reported when the take closes
  std::atomic<bool> active_{false};

  mutable std::mutex mutex_;  // control requests and error, between the caller and the recorder thread
  std::optional<std::filesystem::path> start_request_;
  bool stop_request_ = false;
  bool quit_ = false;
  std::optional<std::string> error_;

  // Recorder thread's.
  UniqueFd fd_;
  std::filesystem::path file_;
  std::chrono::steady_clock::time_point last_sync_;
  fmt::memory_buffer lines_;
  bool header_pending_ = false;      // the header waits for the take's first row (its timecode)
  bool sound_zero_pending_ = false;  // the sound waits for the take's first row (its capture time)
  std::optional<std::int64_t> last_row_ns_;  // capture time of the take's last row so far: where its sound ends

  std::thread thread_;
};

}  // namespace lipdrive
