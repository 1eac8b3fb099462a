// A Video4Linux2 capture device (USB/UVC cameras, CSI bridges with a single-planar
// capture node) as a FrameSource: memory-mapped streaming, the luma and Cr planes.
//
// Thread model: one thread owns a V4l2Camera and makes every call on it (construction,
// grab, accessors, destruction). It starts no threads and takes no locks; the device is
// opened non-blocking and grab() waits in poll() with the caller's timeout.
//
// Lifetime of frames: Frame::gray points into a mmapped driver buffer (GREY, NV12), into
// a luma buffer the camera reuses (YUYV, and an interlaced frame's first field brought back to
// full height) or into a freshly decoded image (MJPEG); Frame::cr (empty for GREY) into a Cr
// buffer the camera reuses. The driver buffer is handed back at the
// start of the next grab(), so a frame is valid until then.
//
// Disconnects: when the device goes away (ENODEV/EIO/ENXIO, or POLLERR) every resource is
// released at once and grab() returns kDisconnected; later grabs reopen the device with
// exponential back-off, never waiting longer than their timeout, and frames flow again
// without recreating the camera.
#pragma once

#include "core/backoff.hpp"
#include "drivers/frame_source.hpp"
#include "drivers/image_codec.hpp"
#include "drivers/system_calls.hpp"

#include <linux/videodev2.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

namespace lipdrive {
namespace detail {
class V4l2Stream;  // an open, streaming device: fd and mapped buffers (RAII)
}

enum class PixelFormat { kAuto, kGrey, kNv12, kYuyv, kMjpeg };

/// "auto", "GREY", "NV12", "YUYV", "MJPEG" (case-insensitive); throws std::invalid_argument
/// naming the value and the accepted ones.
PixelFormat parse_pixel_format(std::string_view name);
std::string_view pixel_format_name(PixelFormat format);

/// Image controls, set every time the device is opened (a replugged camera has forgotten
/// them). A head rig under stage light wants a fixed, short exposure: automatic exposure pumps
/// with the lights (and with it the lips' brightness the pixel measures read), and a long one
/// blurs fast lip movement. A control the camera lacks, or a value outside its range (clamped
/// to it), is logged naming the device; the camera still delivers frames.
struct V4l2Controls {
  int exposure_us = 0;     // 0: the camera's automatic exposure; else manual, this long (100 µs steps)
  int gain = -1;           // -1: as the camera sets it; else V4L2_CID_GAIN in the driver's units
  int power_line_hz = -1;  // -1: as the camera sets it; 0: no anti-flicker filter; 50 or 60 Hz mains
  /// Automatic exposure may not lower the frame rate in the dark (a UVC camera's
  /// V4L2_CID_EXPOSURE_AUTO_PRIORITY set to 0): the figure's latency follows the frame period.
  /// Set only where the camera offers the control (a camera without it logs nothing); false
  /// leaves the camera's own setting.
  bool keep_frame_rate = true;
};

struct V4l2Options {
  /// A path (/dev/video0) or a name under /dev/v4l/by-id/ (usb-Vendor_Cam-video-index0).
  /// A by-id name survives re-enumeration: after an unplug the same camera is reopened
  /// even if it comes back as another /dev/videoN.
  std::string device = "/dev/video0";
  /// kAuto picks the first the device offers of NV12, YUYV, GREY, MJPEG: colour with a luma
  /// plane first (the lip contact reads Cr; NV12's luma needs no copy), then luma alone, JPEG
  /// decoding last.
  PixelFormat format = PixelFormat::kAuto;
  unsigned width = 0;     // 0 keeps the device's current size
  unsigned height = 0;    // 0 keeps the device's current size
  double frame_rate = 0;  // frames per second; 0 keeps the device's current rate
  unsigned buffer_count = 4;
  V4l2Controls controls;
  std::chrono::milliseconds reconnect_initial{100};
  std::chrono::milliseconds reconnect_max{5000};
};

/// What the driver agreed to: it may adjust the requested size and rate.
struct V4l2Negotiated {
  std::string card;  // VIDIOC_QUERYCAP card name, for logs
  PixelFormat format = PixelFormat::kAuto;
  unsigned width = 0;
  unsigned height = 0;
  unsigned bytes_per_line = 0;
  unsigned image_size = 0;  // bytes per buffer the driver fills at most
  std::uint32_t field = V4L2_FIELD_NONE;  // how a frame holds its fields (an analogue grabber's are interlaced)
  double frame_rate = 0;    // 0 if the driver does not report it
  unsigned buffer_count = 0;
};

struct V4l2Counters {
  std::uint64_t delivered = 0;    // frames returned as kFrame
  std::uint64_t dropped = 0;      // gaps in the driver's buffer sequence numbers
  std::uint64_t corrupt = 0;      // buffers flagged with an error, too short or undecodable
  std::uint64_t disconnects = 0;  // times the device went away
  std::uint64_t reconnects = 0;   // times it was reopened afterwards
};

/// The node V4l2Options::device names: the path itself, or a name's under /dev/v4l/by-id/.
std::string v4l2_device_path(const std::string& device);

class V4l2Camera final : public FrameSource {
 public:
  /// Opens, negotiates and starts streaming; throws SourceError naming the device and the
  /// reason (not a streaming capture device, no supported format, ...). A device node that is
  /// not there (yet) is not an error: the camera starts disconnected (connected() false,
  /// reconnect_error() says why) and grab() opens it when it appears, with the back-off of a
  /// camera unplugged while streaming.
  explicit V4l2Camera(V4l2Options options, SystemCalls& system = real_system_calls());
  ~V4l2Camera() override;
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) override;
  /// The stream's rate; before the first stream opened, the rate asked for (0 if none).
  double frame_rate() const override {
    return negotiated_.frame_rate > 0 ? negotiated_.frame_rate : options_.frame_rate;
  }
  std::string describe() const override { return path_; }

  /// The format of the current (or, while disconnected, the last) stream.
  const V4l2Negotiated& negotiated() const { return negotiated_; }
  const V4l2Counters& counters() const { return counters_; }
  bool connected() const { return stream_ != nullptr; }
  /// Why the last reconnect attempt failed; empty when none failed.
  const std::string& reconnect_error() const { return reconnect_error_; }

 private:
  using Clock = std::chrono::steady_clock;

  bool reconnect_before(Clock::time_point deadline);
  void start_stream();
  void disconnect();
  GrabStatus fail(int error, const char* call);
  GrabStatus deliver(const v4l2_buffer& buffer, Frame& frame);
  std::uint64_t sequence_for(std::uint32_t driver_sequence);
  cv::Mat luma_of(const void* data, std::uint32_t bytes_used);
  void read_first_field(cv::Mat& gray);

  V4l2Options options_;
  SystemCalls& system_;
  std::string path_;
  V4l2Negotiated negotiated_;
  V4l2Counters counters_;
  std::unique_ptr<detail::V4l2Stream> stream_;
  cv::Mat luma_;  // YUYV's luma plane or MJPEG's decoded one, reused for every frame
  cv::Mat cr_;    // the Cr plane of YUYV, NV12 or MJPEG, the same; empty for GREY
  cv::Mat field_luma_, field_cr_;      // an interlaced frame's first field at the frame's size
  std::unique_ptr<JpegDecoder> jpeg_;  // MJPEG streams

  // Sequence bookkeeping: Frame::sequence keeps counting across reconnects, and the driver
  // restarts its own numbering with every stream.
  std::uint64_t next_sequence_ = 0;
  bool stream_started_ = false;  // a buffer of the current stream has been seen
  std::uint32_t expected_driver_sequence_ = 0;
  std::int64_t first_capture_ns_ = -1;

  Clock::time_point next_reconnect_{};
  Backoff reconnect_backoff_;
  std::string reconnect_error_;
};

}  // namespace lipdrive
