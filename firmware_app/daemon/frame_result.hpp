// What the processing thread makes of one frame, and who may see it on that thread.
#pragma once

#include "core/drive_signals.hpp"
#include "core/drive_source.hpp"
#include "core/mouth_measures.hpp"
#include "core/viseme_weights.hpp"

#include <cstdint>

namespace lipdrive {

/// The result of one processed frame; trivially copyable so it can cross threads through a
/// seqlock. The neutral result (default-constructed) is "not tracked, all zero".
struct FrameResult {
  std::uint64_t sequence = 0;          // the source's frame sequence number
  std::int64_t capture_time_ns = 0;    // CLOCK_MONOTONIC at capture
  std::int64_t processed_time_ns = 0;  // CLOCK_MONOTONIC when the measures were ready
  double media_time_s = 0;
  bool tracked = false;
  MouthMeasures measures;      // valid when tracked, zero otherwise
  VisemeWeights visemes{};     // FrameMeasurement::visemes when tracked, zero otherwise
  DriveSignals signals;        // calibrated values for the drive, zero when not tracked
  bool side_used = false;      // protrusion came from the side camera (protrusion_side)
  double protrusion_side = 0;  // side-view protrusion over the nose length, when side_used
  int width = 0, height = 0;   // frame size in pixels
  std::int32_t timecode = -1;  // frame number (core/timecode.hpp) at capture; -1: not stamped
  // Who drives at this frame: the tracked face, else the voice while it is heard, else the fail-safe.
  DriveSource drive = DriveSource::kFailSafe;
};

/// Sees every result on the processing thread, in order (the take recorder, tests). push()
/// must neither block nor allocate.
class ResultSink {
 public:
  virtual ~ResultSink() = default;
  virtual void push(const FrameResult& result) = 0;
};

}  // namespace lipdrive
