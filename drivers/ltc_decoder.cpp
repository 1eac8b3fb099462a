#include "drivers/ltc_decoder.hpp"

#include <ltc.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lipdrive {
namespace {

// Decoded frames libltc holds until read(); the owner reads after every block.
constexpr int kQueueSize = 32;

}  // namespace

LtcDecoder::LtcDecoder(int sample_rate, double expected_fps) : sample_rate_(sample_rate) {
  const double samples_per_frame = sample_rate / (expected_fps > 0 ? expected_fps : 25.0);
  decoder_ = ltc_decoder_create(static_cast<int>(std::lround(samples_per_frame)), kQueueSize);
  if (!decoder_) throw std::runtime_error("libltc: cannot create an LTC decoder");
}

LtcDecoder::~LtcDecoder() { ltc_decoder_free(decoder_); }

void LtcDecoder::write(std::span<const float> samples, int sample_rate, std::int64_t first_sample_time_ns) {
  if (sample_rate <= 0) return;
  sample_rate_ = sample_rate;
  block_position_ = position_;
  block_time_ns_ = first_sample_time_ns;
  // libltc takes a mutable pointer but only reads the samples.
  ltc_decoder_write_float(decoder_, const_cast<float*>(samples.data()), samples.size(), position_);
  position_ += static_cast<std::int64_t>(samples.size());
}

bool LtcDecoder::read(LtcFrame& frame) {
  LTCFrameExt decoded;
  if (ltc_decoder_read(decoder_, &decoded) == 0) return false;
  SMPTETimecode time;
  ltc_frame_to_time(&time, &decoded.ltc, 0);
  frame.hours = time.hours;
  frame.minutes = time.mins;
  frame.seconds = time.secs;
  frame.frames = time.frame;
  frame.drop_frame = decoded.ltc.dfbit != 0;
  frame.reverse = decoded.reverse != 0;
  // Playing backwards, the frame begins at its end.
  const std::int64_t first = decoded.reverse ? decoded.off_end : decoded.off_start;
  frame.start_time_ns = block_time_ns_ + (first - block_position_) * 1'000'000'000 / std::max(sample_rate_, 1);
  frame.volume_dbfs = decoded.volume;
  return true;
}

}  // namespace lipdrive
