// The optional side camera (DESIGN.md 4.4): upper-lip protrusion from the profile, paired
// with front frames by capture time.
//
// Thread model: the side camera's own capture thread owns the FrameSource and hands frames to
// the pipeline's processing thread through a latest-frame-wins triple buffer; everything else
// (pairing, the reference, the measurement) runs on the processing thread. When the side
// camera fails or ends, protrusion_near() returns nothing and the front camera carries on
// alone (protrusion then comes from the 3D fit).
#pragma once

#include "core/side_profile.hpp"
#include "drivers/frame_source.hpp"
#include "firmware_app/latest_frame.hpp"

#include <atomic>
#include <memory>
#include <optional>
#include <thread>
#include <vector>

namespace lipdrive {

class SideCamera {
 public:
  /// The reference line is fixed on the first `neutral_frames` side frames, and again on as
  /// many frames after each recalibrate().
  SideCamera(std::unique_ptr<FrameSource> source, SideProfileSettings settings, int neutral_frames);
  ~SideCamera();
  SideCamera(const SideCamera&) = delete;
  SideCamera& operator=(const SideCamera&) = delete;

  void start();
  void stop();

  /// Processing thread: the protrusion of the side frame nearest to `front_time_ns`, if one
  /// lies within `half_period_ns`. Waits at most until front_time_ns + half_period_ns for a
  /// side frame that is still due. Nothing while the reference is being fixed or the profile
  /// cannot be measured.
  std::optional<double> protrusion_near(std::int64_t front_time_ns, std::int64_t half_period_ns);

  /// Any thread: fix the reference line again on the next neutral frames.
  void recalibrate() { recalibrate_.store(true, std::memory_order_relaxed); }
  bool connected() const { return connected_.load(std::memory_order_relaxed); }
  std::string describe() const { return description_; }

 private:
  struct SideFrame {
    cv::Mat gray;
    std::int64_t capture_time_ns = 0;
  };
  void capture_loop();
  /// The current side frame, newer if one arrives before `deadline_ns` and it is still due.
  const SideFrame* nearest(std::int64_t front_time_ns, std::int64_t half_period_ns);

  std::unique_ptr<FrameSource> source_;
  std::string description_;
  LatestFrame<SideFrame> frames_;
  std::atomic<bool> connected_{false}, stop_{false}, recalibrate_{false};
  std::thread thread_;

  // Processing thread's.
  SideProfileMeter meter_;
  std::optional<SideReference> reference_;
  std::vector<cv::Mat> neutral_;  // the frames the reference is being fixed on
  int neutral_frames_;
  const SideFrame* current_ = nullptr;
};

}  // namespace lipdrive
