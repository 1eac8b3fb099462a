#include "firmware_app/daemon/take_sound.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <span>

namespace lipdrive {

void TakeSound::push(const AudioBlock& block) { ring_.push(block); }

void TakeSound::open(const std::filesystem::path& file) {
  close();
  zero_ns_.reset();
  ring_.clear();  // older sound is not the take's
  ring_.take_dropped();
  future_blocks_ = 0;
  try {
    file_.emplace(file, sample_rate_);
  } catch (const AudioSourceError& e) {
    spdlog::error("{}; the take is recorded without its sound", e.what());
  }
}

void TakeSound::drain() {
  if (!file_) {
    ring_.clear();  // without an open take (or after a write error) dropped
    return;
  }
  if (!zero_ns_) {
    // The blocks wait for the take's first row. What is heard before it is not the take's
    // (write() would cut it): while the camera is away the ring keeps the last half second, so
    // that a long wait does not fill it and count the sound lost.
    const std::int64_t before = now_ns_() - kBehind;
    for (const AudioBlock* block = ring_.front(); block && block->capture_time_ns <= before; block = ring_.front())
      ring_.pop();
    return;
  }
  take_blocks(kBehind, std::nullopt);
}

void TakeSound::take_blocks(std::int64_t behind_ns, std::optional<std::int64_t> end_ns) {
  const std::int64_t now = now_ns_();
  while (const AudioBlock* block = ring_.front()) {
    if (block->capture_time_ns > now) {  // read after the block was queued
      ++future_blocks_;
    } else {
      if (block->capture_time_ns > now - behind_ns) return;  // held
      if (file_) write(*block, end_ns);
    }
    ring_.pop();
  }
}

void TakeSound::write(const AudioBlock& block, std::optional<std::int64_t> end_ns) {
  // Where the block's first sample lies in the file. A block a few samples early or late of
  // where the last one ended (clock jitter) continues it; a later one leaves a gap of silence;
  // sound from before the file's end (or its start) is cut.
  const auto start = static_cast<std::int64_t>(
      std::llround(static_cast<double>(block.capture_time_ns - *zero_ns_) * block.sample_rate * 1e-9));
  const std::int64_t written = file_->samples(), slack = block.sample_rate / 500;  // 2 ms
  const std::int64_t skip = start < written - slack ? written - start : 0;
  const std::int64_t frames =
      end_ns ? std::clamp<std::int64_t>(static_cast<std::int64_t>(static_cast<double>(*end_ns - block.capture_time_ns) *
                                                                  block.sample_rate * 1e-9),
                                        0, block.frames)
             : block.frames;
  if (skip >= frames) return;
  try {
    if (start > written + slack) file_->write_silence(start - written);
    file_->write(std::span(block.samples.data() + skip, static_cast<std::size_t>(frames - skip)));
  } catch (const AudioSourceError& e) {
    spdlog::error("{}; the rest of the take is recorded without its sound", e.what());
    file_.reset();
  }
}

void TakeSound::close(std::optional<std::int64_t> end_ns) {
  if (!file_) return;
  if (zero_ns_) take_blocks(0, end_ns);
  if (!file_) return;
  try {
    file_->close();
  } catch (const AudioSourceError& e) {
    spdlog::error("{}", e.what());
  }
  file_.reset();
  if (const std::uint64_t lost = ring_.take_dropped(); lost > 0)
    spdlog::warn("take sound: {} blocks were lost because the recorder could not keep up", lost);
  if (future_blocks_ > 0)
    spdlog::warn("take sound: {} blocks were stamped later than the clock read (the audio clock jumped ahead) and "
                 "were left out",
                 future_blocks_);
}

}  // namespace lipdrive
