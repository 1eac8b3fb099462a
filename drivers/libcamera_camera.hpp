// A libcamera camera (CSI sensors behind an ISP, e.g. on Raspberry Pi boards) as a
// FrameSource: one Viewfinder stream in a luma-first format (YUV420, NV12, YVU420, NV21, or
// R8 from a monochrome sensor), its luma plane and, but for R8, the Cr samples the lip
// contact reads (drivers/chroma_420.hpp).
//
// Thread model: one thread owns a LibcameraCamera and makes every call on it. libcamera
// completes requests on a thread of its own (the CameraManager's); its requestCompleted and
// disconnected callbacks only put the request on a mutex-guarded queue (or set a flag) and
// notify a condition variable, and grab() waits on that with the caller's timeout. The
// buffers, requests and the camera itself are touched by the owner thread only.
//
// Lifetime of frames: Frame::gray and Frame::cr point into the mmapped buffer of a completed
// request (the Cr of NV12 and NV21 into the camera's own plane, gathered from the pairs); the
// request goes back to the camera at the start of the next grab(), so a frame is valid until
// then.
//
// Disconnects: when libcamera reports the camera gone, everything of it is released and
// grab() returns kDisconnected; later grabs look for the same camera id again with
// exponential back-off (100 ms up to 5 s), never waiting longer than their timeout. A camera
// not there at construction (none at all, or none by the configured id) is, with
// wait_when_absent, waited for the same way: the daemon started at boot before the sensor and
// its ISP were enumerated runs until they are.
//
// libcamera's API is not stable: this is written against 0.0.3 (Debian 12). The calls known
// to differ in newer releases are confined to libcamera_camera.cpp, marked "libcamera API:":
//   - 0.1: Camera::generateConfiguration() takes a Span<const StreamRole> instead of the
//     StreamRoles vector (alias removed); a std::vector<StreamRole> converts to both.
//   - 0.2: CameraConfiguration::transform became `orientation` (not used here).
//   - FrameDurationLimits is set through a Span<const int64_t, 2>, the form every version
//     accepts (0.0.3 also takes an initializer_list).
// In every version only one CameraManager may exist per process, so all cameras share one.
#pragma once

#include "drivers/frame_source.hpp"

#include <chrono>
#include <memory>
#include <string>

namespace lipdrive {

struct LibcameraOptions {
  std::string camera_id;  // as `cam --list` shows it; "" = the first camera
  unsigned width = 0;     // 0 keeps the camera's default size for the viewfinder role
  unsigned height = 0;
  double frame_rate = 0;  // frames per second; 0 keeps the camera's default
  int exposure_us = 0;    // 0: the camera's automatic exposure; else manual, this long ([camera.controls])
  /// A camera not there (yet) is waited for, as after a disconnect (the daemon); false: it is
  /// an error at once (`lipdrive calibrate` on the camera).
  bool wait_when_absent = false;
};

class LibcameraCamera final : public FrameSource {
 public:
  /// Starts libcamera, acquires and configures the camera and starts streaming; throws
  /// SourceError naming the camera and the reason (busy, no luma-first format, ...). A camera
  /// that is not there ("libcamera: no cameras found", no camera by that id) throws too unless
  /// options.wait_when_absent: then that is logged once ("...; waiting for it") and grab()
  /// returns kDisconnected until the camera appears and opens.
  explicit LibcameraCamera(LibcameraOptions options);
  ~LibcameraCamera() override;
  LibcameraCamera(const LibcameraCamera&) = delete;
  LibcameraCamera& operator=(const LibcameraCamera&) = delete;

  GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) override;
  /// The requested rate when the camera accepted a frame-duration control, else 0; the
  /// requested rate until the camera has opened.
  double frame_rate() const override;
  /// "libcamera:" and the camera id ("libcamera:(first camera)" for no id until one is found).
  std::string describe() const override;

 private:
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace lipdrive
