// A take's sound (docs/voice.md "Training on takes"): the voice input's blocks, heard on the
// voice room's listener thread, written beside the take's CSV as a WAV file of the same name
// by the take recorder's thread. The file's first sample was captured at the capture_time_ns
// of the take's first row, so rows and sound share one timeline: sample k at that time plus
// k / rate. Lost blocks and a sound that starts late are filled with silence; what came before
// the first row is cut. A block stamped later than the clock reads (an audio clock that jumped
// ahead) is left out rather than filled up to with silence: the silence a gap adds is bounded
// by the time that really passed. The recorder writes the sound half a second behind the clock
// (kBehind), so that when the take stops its sound can end with its last row: what was heard
// after that row is cut. A stretch without rows inside a take (the camera gone) keeps its sound.
//
// Thread model: push() is called by one thread, the audio listener's: it never blocks and never
// allocates (a full ring drops the block, counted). Every other call is made by the take
// recorder's thread. The Daemon declares the TakeSound before the voice room and the recorder,
// so both threads are joined before it goes.
#pragma once

#include "drivers/audio_file.hpp"
#include "drivers/audio_source.hpp"
#include "drivers/clock.hpp"
#include "firmware_app/daemon/latest_frame.hpp"

#include <cstdint>
#include <filesystem>
#include <optional>

namespace lipdrive {

class TakeSound {
 public:
  /// `now_ns` reads the clock the blocks are stamped on (a test passes its own).
  explicit TakeSound(int sample_rate, std::int64_t (*now_ns)() = &monotonic_ns)
      : sample_rate_(sample_rate), now_ns_(now_ns) {}
  TakeSound(const TakeSound&) = delete;
  TakeSound& operator=(const TakeSound&) = delete;

  /// Listener thread: queues a block.
  void push(const AudioBlock& block);

  /// Recorder thread: begins the sound of a take in `file` (replaced if it exists). A file that
  /// cannot be created is logged; the take goes on without sound.
  void open(const std::filesystem::path& file);
  /// Recorder thread: the capture time of the take's first row, the file's time zero. Blocks
  /// wait in the ring until it is known.
  void start_at(std::int64_t first_row_ns) { zero_ns_ = first_row_ns; }
  /// Recorder thread: writes the queued blocks captured more than kBehind ago (without an open
  /// take, drops every queued block).
  void drain();
  /// Recorder thread: writes what is queued, up to `end_ns` when given (the capture time of the
  /// take's last row), and closes the file.
  void close(std::optional<std::int64_t> end_ns = std::nullopt);

 private:
  static constexpr std::size_t kRingSize = 256;  // 2.5 s of the voice room's 10 ms blocks
  static constexpr std::int64_t kBehind = 500'000'000;  // ns: the ring holds five times this

  // Writes the block's samples captured before `end_ns` (all without one) where they belong.
  void write(const AudioBlock& block, std::optional<std::int64_t> end_ns);
  // Takes the queued blocks captured at least `behind_ns` before now off the ring (0: every one)
  // and writes them, each cut at `end_ns`; a block stamped after now is counted and left out.
  void take_blocks(std::int64_t behind_ns, std::optional<std::int64_t> end_ns);

  int sample_rate_;
  std::int64_t (*now_ns_)();
  SingleProducerRing<AudioBlock, kRingSize> ring_;  // full: blocks lost, reported when the take closes

  // Recorder thread's.
  std::optional<WavWriter> file_;
  std::optional<std::int64_t> zero_ns_;
  std::uint64_t future_blocks_ = 0;  // stamped later than the clock read: left out, reported at close
};

}  // namespace lipdrive
