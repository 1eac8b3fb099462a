// The optional side camera (docs/method.md 4): upper-lip protrusion from the profile, paired
// with front frames by capture time.
//
// Thread model: the side camera's own capture thread (capture.hpp) owns the FrameSource and
// hands frames to the pipeline's processing thread through a latest-frame-wins triple
// buffer; everything else (pairing, the reference, the measurement) runs on the processing
// thread. When the side camera fails or ends, protrusion_near() returns nothing and the
// front camera carries on alone (protrusion then comes from the 3D fit).
#pragma once

#include "core/side_profile.hpp"
#include "drivers/frame_source.hpp"
#include "firmware_app/daemon/capture.hpp"

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lipdrive {

/// What the monitor's preview shows of the side camera: its newest frame and that frame's
/// profile.
struct SideView {
  const cv::Mat* gray = nullptr;  // nullptr before the first side frame
  SideProfile profile;            // in frame pixels; see profile.status for how far it got
  bool connected = false;
};

class SideCamera {
 public:
  /// The reference line is fixed on the first `neutral_frames` side frames, and again on as
  /// many frames after each recalibrate().
  SideCamera(std::unique_ptr<FrameSource> source, SideProfileSettings settings, int neutral_frames);

  /// Starts the side camera's capture thread; see Capture::start.
  std::string start(int realtime_priority) { return capture_.start("lipdrive-side", realtime_priority); }
  void stop() { capture_.stop(); }

  /// Processing thread: the protrusion of the side frame nearest to `front_time_ns`, if one
  /// lies within `half_period_ns`. Waits at most until front_time_ns + half_period_ns for a
  /// side frame that is still due. Nothing while the reference is being fixed or the profile
  /// cannot be measured.
  std::optional<double> protrusion_near(std::int64_t front_time_ns, std::int64_t half_period_ns);

  /// Processing thread: fix the reference line again on the next neutral frames.
  void recalibrate() {
    reference_.reset();
    neutral_count_ = 0;
  }
  /// Processing thread, a few times a second for the monitor's preview: the newest side frame
  /// (taken without waiting) and its profile, found again only when the frame was not the one
  /// just measured. The frame stays valid until the processing thread next calls this or
  /// protrusion_near().
  SideView view();

  bool connected() const { return capture_.delivering(); }
  const std::string& describe() const { return capture_.describe(); }

 private:
  /// The current side frame, newer if one arrives before `deadline_ns` and it is still due.
  const CapturedFrame* nearest(std::int64_t front_time_ns, std::int64_t half_period_ns);

  Capture capture_;

  // Processing thread's.
  SideProfileMeter meter_;
  std::optional<SideReference> reference_;
  // The frames the reference is being fixed on: neutral_frames of them, whose pixels are
  // allocated with the first side frames and reused by every attempt after.
  std::vector<cv::Mat> neutral_;
  int neutral_count_ = 0;
  bool failing_ = false;  // the last attempt failed: the next failures are not logged again
  const CapturedFrame* current_ = nullptr;
  SideProfile profile_;                 // of the side frame measured last
  const CapturedFrame* profiled_ = nullptr;  // that frame
  std::uint64_t profiled_sequence_ = 0;
};

}  // namespace lipdrive
