#include "drivers/v4l2_camera.hpp"

#include "drivers/chroma_420.hpp"
#include "drivers/clock.hpp"
#include "drivers/image_codec.hpp"
#include "drivers/unique_fd.hpp"

#include <fcntl.h>
#include <sys/mman.h>

#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace lipdrive {
namespace detail {

/// Owns what an open stream holds in the kernel, and gives it back in reverse order.
/// Built step by step while opening, so a failure half-way releases exactly what was taken.
class V4l2Stream {
 public:
  struct MappedBuffer {
    void* data;
    std::size_t length;
  };

  V4l2Stream(SystemCalls& system, int fd) : system(system), owned_fd(fd, system), fd(fd) {}
  ~V4l2Stream() {
    if (streaming) {
      // Fails with ENODEV after an unplug; the buffers are released all the same.
      v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      system.ioctl(fd, VIDIOC_STREAMOFF, &type);
    }
    for (const MappedBuffer& buffer : buffers) system.munmap(buffer.data, buffer.length);
    // owned_fd closes the device last, after the buffers are unmapped.
  }
  V4l2Stream(const V4l2Stream&) = delete;
  V4l2Stream& operator=(const V4l2Stream&) = delete;

  SystemCalls& system;
  const UniqueFd owned_fd;
  const int fd;  // owned_fd.get()
  std::vector<MappedBuffer> buffers;
  bool streaming = false;
  int held = -1;  // index of the buffer the caller is reading, -1 if none
};

}  // namespace detail

namespace {

/// Whether a frame of this field order holds two fields, captured half a frame period apart.
bool holds_two_fields(std::uint32_t field) {
  return field == V4L2_FIELD_INTERLACED || field == V4L2_FIELD_INTERLACED_TB || field == V4L2_FIELD_INTERLACED_BT ||
         field == V4L2_FIELD_SEQ_TB || field == V4L2_FIELD_SEQ_BT;
}

/// The rows of a plane that hold a frame's first field in time (videodev2.h's field orders):
/// every second row from the top (the bottom field first: from the second), or the first half
/// of a frame whose fields are stored one after the other, older first. V4L2_FIELD_INTERLACED
/// leaves the order to the video standard: the bottom field first in NTSC's 480 lines, the top
/// one otherwise.
cv::Mat first_field(const cv::Mat& plane, const V4l2Negotiated& negotiated) {
  const auto every_second_row = [&plane](int first) {
    return cv::Mat(plane.rows / 2, plane.cols, plane.type(), plane.data + first * plane.step[0], 2 * plane.step[0]);
  };
  switch (negotiated.field) {
    case V4L2_FIELD_INTERLACED_TB: return every_second_row(0);
    case V4L2_FIELD_INTERLACED_BT: return every_second_row(1);
    case V4L2_FIELD_INTERLACED: return every_second_row(negotiated.height == 480 ? 1 : 0);
    default: return plane.rowRange(0, plane.rows / 2);  // V4L2_FIELD_SEQ_TB, V4L2_FIELD_SEQ_BT
  }
}

/// A field's rows (8-bit, one channel) at `frame`'s height, which is about twice theirs: each
/// row, then its mean with the next one. Allocates nothing.
void to_frame_height(const cv::Mat& field, cv::Mat& frame) {
  for (int y = 0; y < frame.rows; ++y) {
    const int row = std::min(y / 2, field.rows - 1), below = std::min(row + y % 2, field.rows - 1);
    const std::uint8_t* a = field.ptr<std::uint8_t>(row);
    const std::uint8_t* b = field.ptr<std::uint8_t>(below);
    std::uint8_t* out = frame.ptr<std::uint8_t>(y);
    for (int x = 0; x < frame.cols; ++x) out[x] = static_cast<std::uint8_t>((a[x] + b[x] + 1) / 2);
  }
}

using detail::V4l2Stream;

// Colour with a luma plane first (the lip contact reads Cr), then luma alone, JPEG decoding last.
constexpr std::array kAutoOrder = {PixelFormat::kNv12, PixelFormat::kYuyv, PixelFormat::kGrey, PixelFormat::kMjpeg};
constexpr const char* kByIdDirectory = "/dev/v4l/by-id/";

std::string error_text(int error) { return std::generic_category().message(error); }

/// The errors with which the kernel reports a device that is gone (USB unplug, bridge
/// reset): everything else mid-stream is a bug that reopening would not fix.
bool is_disconnect(int error) { return error == ENODEV || error == EIO || error == ENXIO; }

std::uint32_t fourcc_of(PixelFormat format) {
  switch (format) {
    case PixelFormat::kGrey: return V4L2_PIX_FMT_GREY;
    case PixelFormat::kNv12: return V4L2_PIX_FMT_NV12;
    case PixelFormat::kYuyv: return V4L2_PIX_FMT_YUYV;
    case PixelFormat::kMjpeg: return V4L2_PIX_FMT_MJPEG;
    case PixelFormat::kAuto: break;
  }
  throw std::logic_error("PixelFormat::kAuto has no fourcc");
}

std::string fourcc_text(std::uint32_t fourcc) {
  std::string text;
  for (int shift = 0; shift < 32; shift += 8) text += static_cast<char>((fourcc >> shift) & 0xff);
  return text;
}

std::string fourcc_list(const std::vector<std::uint32_t>& fourccs) {
  if (fourccs.empty()) return "none";
  std::string text;
  for (std::uint32_t fourcc : fourccs) text += (text.empty() ? "" : ", ") + fourcc_text(fourcc);
  return text;
}

/// Bytes of one row of the luma plane with no padding, 0 for compressed formats.
unsigned packed_bytes_per_line(PixelFormat format, unsigned width) {
  return format == PixelFormat::kYuyv ? 2 * width : format == PixelFormat::kMjpeg ? 0 : width;
}

/// The fewest bytes a complete frame of the format can have; a driver reporting fewer
/// delivered a truncated frame.
std::size_t minimum_image_bytes(const V4l2Negotiated& negotiated) {
  const std::size_t plane = std::size_t{negotiated.bytes_per_line} * negotiated.height;
  switch (negotiated.format) {
    case PixelFormat::kNv12: return plane + plane / 2;  // full-size Y, half-height interleaved UV
    case PixelFormat::kMjpeg: return 1;
    default: return plane;
  }
}

/// The device node is not there, went away while it was being opened, or is not yet the
/// service's to open (udev gives a new node its group a moment after it appears).
struct DeviceAbsent : SourceError {
  using SourceError::SourceError;
};

/// The steps of opening a stream, sharing the device, its path (for messages) and the
/// stream that collects the resources.
class StreamOpener {
 public:
  StreamOpener(SystemCalls& system, const std::string& path) : system_(system), path_(path) {}

  std::unique_ptr<V4l2Stream> open(const V4l2Options& options, V4l2Negotiated& negotiated) {
    // Non-blocking: grab() waits in poll() with its own timeout, and DQBUF never hangs.
    const int fd = system_.open(path_.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd == -1) fail_with_errno("cannot open the device");
    stream_ = std::make_unique<V4l2Stream>(system_, fd);

    negotiated.card = query_capture_card();
    negotiated.format = choose_format(options.format);
    set_format(options, negotiated);
    negotiated.frame_rate = set_frame_rate(options.frame_rate);
    set_controls(options.controls);
    negotiated.buffer_count = map_buffers(options.buffer_count);
    start_streaming();
    return std::move(stream_);
  }

 private:
  [[noreturn]] void fail(const std::string& reason) const { throw SourceError(path_ + ": " + reason); }

  /// For a call that just failed: errno is read before anything else can change it.
  [[noreturn]] void fail_with_errno(const char* what) const {
    const int error = errno;
    const std::string reason = path_ + ": " + what + ": " + error_text(error);
    if (error == ENOENT || error == EACCES || is_disconnect(error)) throw DeviceAbsent(reason);
    throw SourceError(reason);
  }

  void require(unsigned long request, void* argument, const char* what) {
    if (system_.ioctl(stream_->fd, request, argument) == -1) fail_with_errno(what);
  }

  std::string query_capture_card() {
    v4l2_capability capability{};
    if (system_.ioctl(stream_->fd, VIDIOC_QUERYCAP, &capability) == -1)
      fail_with_errno("not a V4L2 device (VIDIOC_QUERYCAP)");
    // device_caps describes this node; capabilities covers the whole physical device.
    const std::uint32_t caps =
        (capability.capabilities & V4L2_CAP_DEVICE_CAPS) ? capability.device_caps : capability.capabilities;
    if (!(caps & V4L2_CAP_VIDEO_CAPTURE))
      fail((caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) ? "is a multi-planar capture device, which is not supported"
                                                  : "is not a video capture device");
    if (!(caps & V4L2_CAP_STREAMING)) fail("does not support streaming I/O");
    return reinterpret_cast<const char*>(capability.card);
  }

  std::vector<std::uint32_t> offered_formats() {
    std::vector<std::uint32_t> fourccs;
    v4l2_fmtdesc description{};
    description.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    while (system_.ioctl(stream_->fd, VIDIOC_ENUM_FMT, &description) == 0) {
      fourccs.push_back(description.pixelformat);
      ++description.index;
    }
    return fourccs;
  }

  PixelFormat choose_format(PixelFormat preference) {
    const std::vector<std::uint32_t> offered = offered_formats();
    const auto is_offered = [&](PixelFormat format) {
      return std::ranges::find(offered, fourcc_of(format)) != offered.end();
    };
    if (preference != PixelFormat::kAuto) {
      if (!is_offered(preference))
        fail("does not offer pixel format " + std::string(pixel_format_name(preference)) +
             " (offers: " + fourcc_list(offered) + ")");
      return preference;
    }
    const auto chosen = std::ranges::find_if(kAutoOrder, is_offered);
    if (chosen == kAutoOrder.end())
      fail("offers none of NV12, YUYV, GREY, MJPEG (offers: " + fourcc_list(offered) + ")");
    return *chosen;
  }

  void set_format(const V4l2Options& options, V4l2Negotiated& negotiated) {
    v4l2_format format{};
    format.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    require(VIDIOC_G_FMT, &format, "VIDIOC_G_FMT");
    v4l2_pix_format& pix = format.fmt.pix;
    pix.pixelformat = fourcc_of(negotiated.format);
    if (options.width) pix.width = options.width;
    if (options.height) pix.height = options.height;
    pix.field = V4L2_FIELD_NONE;
    pix.bytesperline = 0;  // let the driver choose its row alignment
    require(VIDIOC_S_FMT, &format, "VIDIOC_S_FMT");
    // Drivers adjust size silently (nearest supported); a changed format is a refusal.
    if (pix.pixelformat != fourcc_of(negotiated.format))
      fail("switched the pixel format to " + fourcc_text(pix.pixelformat) + " instead of " +
           std::string(pixel_format_name(negotiated.format)));
    if (pix.width == 0 || pix.height == 0) fail("negotiated an empty image size");
    negotiated.width = pix.width;
    negotiated.height = pix.height;
    negotiated.bytes_per_line = std::max(pix.bytesperline, packed_bytes_per_line(negotiated.format, pix.width));
    negotiated.image_size = pix.sizeimage;
    negotiated.field = pix.field;
  }

  /// Frame rate is the inverse of VIDIOC_S_PARM's timeperframe; the driver writes back the
  /// interval it chose. Drivers without interval control refuse S_PARM: report their rate.
  double set_frame_rate(double requested) {
    v4l2_streamparm parameters{};
    parameters.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    v4l2_fract& interval = parameters.parm.capture.timeperframe;
    bool known = false;
    if (requested > 0) {
      interval = {1000, static_cast<std::uint32_t>(std::lround(requested * 1000))};
      known = system_.ioctl(stream_->fd, VIDIOC_S_PARM, &parameters) == 0;
    }
    if (!known) known = system_.ioctl(stream_->fd, VIDIOC_G_PARM, &parameters) == 0;
    return known && interval.numerator ? double(interval.denominator) / interval.numerator : 0;
  }

  void set_controls(const V4l2Controls& controls) {
    if (controls.exposure_us > 0 && set_control(V4L2_CID_EXPOSURE_AUTO, V4L2_EXPOSURE_MANUAL, "exposure_auto"))
      set_control(V4L2_CID_EXPOSURE_ABSOLUTE, (controls.exposure_us + 50) / 100, "exposure_absolute (100 µs)");
    if (controls.gain >= 0) set_control(V4L2_CID_GAIN, controls.gain, "gain");
    if (controls.power_line_hz >= 0)
      set_control(V4L2_CID_POWER_LINE_FREQUENCY,
                  controls.power_line_hz == 50   ? V4L2_CID_POWER_LINE_FREQUENCY_50HZ
                  : controls.power_line_hz == 60 ? V4L2_CID_POWER_LINE_FREQUENCY_60HZ
                                                 : V4L2_CID_POWER_LINE_FREQUENCY_DISABLED,
                  "power_line_frequency");
    if (controls.keep_frame_rate) set_control(V4L2_CID_EXPOSURE_AUTO_PRIORITY, 0, "exposure_auto_priority", Missing::kQuiet);
  }

  /// A control the user asked for is missed aloud; one set by default only where it exists.
  enum class Missing { kWarn, kQuiet };

  /// VIDIOC_QUERYCTRL for the control's range, then VIDIOC_S_CTRL with the value clamped to
  /// it; false, logged, when the camera lacks the control or refuses the value.
  bool set_control(std::uint32_t id, std::int32_t value, const char* name, Missing missing = Missing::kWarn) {
    v4l2_queryctrl query{};
    query.id = id;
    if (system_.ioctl(stream_->fd, VIDIOC_QUERYCTRL, &query) == -1 || (query.flags & V4L2_CTRL_FLAG_DISABLED)) {
      spdlog::log(missing == Missing::kWarn ? spdlog::level::warn : spdlog::level::debug,
                  "{}: the camera has no control {}; left as the camera sets it", path_, name);
      return false;
    }
    v4l2_control control{.id = id, .value = std::clamp(value, query.minimum, query.maximum)};
    if (control.value != value)
      spdlog::warn("{}: {} {} is outside the camera's range {}..{}; set to {}", path_, name, value, query.minimum,
                   query.maximum, control.value);
    if (system_.ioctl(stream_->fd, VIDIOC_S_CTRL, &control) == -1) {
      spdlog::warn("{}: the camera refused {} {}: {}", path_, name, control.value, error_text(errno));
      return false;
    }
    return true;
  }

  unsigned map_buffers(unsigned wanted) {
    v4l2_requestbuffers request{};
    // Two at least: the caller reads one while the driver fills another.
    request.count = std::max(wanted, 2u);
    request.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    request.memory = V4L2_MEMORY_MMAP;
    require(VIDIOC_REQBUFS, &request, "VIDIOC_REQBUFS (memory-mapped streaming)");
    if (request.count < 2) fail("granted " + std::to_string(request.count) + " buffer(s), at least 2 are needed");
    for (unsigned index = 0; index < request.count; ++index) {
      v4l2_buffer buffer{};
      buffer.index = index;
      buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buffer.memory = V4L2_MEMORY_MMAP;
      require(VIDIOC_QUERYBUF, &buffer, "VIDIOC_QUERYBUF");
      void* data =
          system_.mmap(nullptr, buffer.length, PROT_READ | PROT_WRITE, MAP_SHARED, stream_->fd, buffer.m.offset);
      if (data == MAP_FAILED) fail_with_errno("mmap of a capture buffer");
      stream_->buffers.push_back({data, buffer.length});
    }
    return request.count;
  }

  void start_streaming() {
    for (unsigned index = 0; index < stream_->buffers.size(); ++index) {
      v4l2_buffer buffer{};
      buffer.index = index;
      buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      buffer.memory = V4L2_MEMORY_MMAP;
      require(VIDIOC_QBUF, &buffer, "VIDIOC_QBUF");
    }
    v4l2_buf_type type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    require(VIDIOC_STREAMON, &type, "VIDIOC_STREAMON");
    stream_->streaming = true;
  }

  SystemCalls& system_;
  const std::string& path_;
  std::unique_ptr<V4l2Stream> stream_;
};

/// CLOCK_MONOTONIC nanoseconds of the capture: the driver's timestamp when it says it is
/// monotonic and it is a time that has passed (seconds from 0, microseconds below a million,
/// not after the dequeue), else the dequeue time (the best bound left). The check comes
/// before any arithmetic: a broken driver's seconds would overflow the conversion.
std::int64_t capture_time_ns(const v4l2_buffer& buffer) {
  const std::int64_t now = monotonic_ns();
  const timeval& t = buffer.timestamp;
  if ((buffer.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) != V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC || t.tv_sec < 0 ||
      t.tv_sec > now / 1'000'000'000 || t.tv_usec < 0 || t.tv_usec >= 1'000'000)
    return now;
  const std::int64_t driver = std::int64_t{t.tv_sec} * 1'000'000'000 + std::int64_t{t.tv_usec} * 1'000;
  return driver <= now ? driver : now;
}

int milliseconds_until(std::chrono::steady_clock::time_point deadline) {
  const auto left = std::chrono::ceil<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
  return static_cast<int>(std::max<std::chrono::milliseconds::rep>(left.count(), 0));
}

}  // namespace

std::string v4l2_device_path(const std::string& device) {
  return device.find('/') == std::string::npos ? kByIdDirectory + device : device;
}

PixelFormat parse_pixel_format(std::string_view name) {
  std::string upper(name);
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  for (PixelFormat format :
       {PixelFormat::kAuto, PixelFormat::kGrey, PixelFormat::kNv12, PixelFormat::kYuyv, PixelFormat::kMjpeg}) {
    std::string known(pixel_format_name(format));
    for (char& c : known) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    if (upper == known) return format;
  }
  throw std::invalid_argument("unknown pixel format '" + std::string(name) +
                              "' (expected auto, GREY, NV12, YUYV or MJPEG)");
}

std::string_view pixel_format_name(PixelFormat format) {
  switch (format) {
    case PixelFormat::kAuto: return "auto";
    case PixelFormat::kGrey: return "GREY";
    case PixelFormat::kNv12: return "NV12";
    case PixelFormat::kYuyv: return "YUYV";
    case PixelFormat::kMjpeg: return "MJPEG";
  }
  return "?";
}

V4l2Camera::V4l2Camera(V4l2Options options, SystemCalls& system)
    : options_(std::move(options)),
      system_(system),
      path_(v4l2_device_path(options_.device)),
      reconnect_backoff_(options_.reconnect_initial, options_.reconnect_max) {
  try {
    start_stream();
  } catch (const DeviceAbsent& absent) {
    // Not there yet: a USB camera enumerated after the daemon started at boot, or unplugged.
    // A camera away, as after an unplug: grab() opens it when it appears.
    spdlog::warn("{}; waiting for it", absent.what());
    reconnect_error_ = absent.what();
    next_reconnect_ = Clock::now() + reconnect_backoff_.failed();
  }
}

V4l2Camera::~V4l2Camera() = default;

void V4l2Camera::start_stream() {
  // Negotiated into a copy: a failed reopen leaves the last stream's description intact.
  V4l2Negotiated negotiated;
  stream_ = StreamOpener(system_, path_).open(options_, negotiated);
  negotiated_ = std::move(negotiated);
  stream_started_ = false;
  // YUYV's luma and the Cr of YUYV and NV12 are gathered here, allocated once per stream;
  // MJPEG's are decoded into them.
  const int height = static_cast<int>(negotiated_.height), width = static_cast<int>(negotiated_.width);
  if (negotiated_.format == PixelFormat::kYuyv)
    luma_.create(height, width, CV_8UC1);
  else
    luma_.release();
  if (negotiated_.format == PixelFormat::kYuyv)
    cr_.create(height, width / 2, CV_8UC1);
  else if (negotiated_.format == PixelFormat::kNv12)
    cr_.create(height / 2, width / 2, CV_8UC1);
  else
    cr_.release();
  if (negotiated_.format == PixelFormat::kMjpeg && !jpeg_) jpeg_ = std::make_unique<JpegDecoder>();
  // A JPEG says itself whether it is interlaced (the decoder reads its first field).
  if (holds_two_fields(negotiated_.field) && negotiated_.format != PixelFormat::kMjpeg) {
    spdlog::info("{}: interlaced frames (V4L2 field order {}): each is read from its first field", path_,
                 negotiated_.field);
    field_luma_.create(height, width, CV_8UC1);
  } else {
    field_luma_.release();
    field_cr_.release();
  }
}

GrabStatus V4l2Camera::grab(Frame& frame, std::chrono::milliseconds timeout) {
  const Clock::time_point deadline = Clock::now() + timeout;
  if (!stream_ && !reconnect_before(deadline)) return GrabStatus::kDisconnected;

  // The previous frame's buffer goes back to the driver only now: the caller was reading it.
  if (stream_->held != -1) {
    v4l2_buffer buffer{};
    buffer.index = static_cast<std::uint32_t>(stream_->held);
    buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buffer.memory = V4L2_MEMORY_MMAP;
    if (system_.ioctl(stream_->fd, VIDIOC_QBUF, &buffer) == -1) return fail(errno, "VIDIOC_QBUF");
    stream_->held = -1;
  }

  pollfd ready{stream_->fd, POLLIN, 0};
  const int count = system_.poll(&ready, 1, milliseconds_until(deadline));
  if (count == -1) return fail(errno, "poll");
  if (count == 0) return GrabStatus::kTimeout;
  if (ready.revents & (POLLERR | POLLHUP | POLLNVAL)) {
    disconnect();
    return GrabStatus::kDisconnected;
  }

  v4l2_buffer buffer{};
  buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buffer.memory = V4L2_MEMORY_MMAP;
  if (system_.ioctl(stream_->fd, VIDIOC_DQBUF, &buffer) == -1) return fail(errno, "VIDIOC_DQBUF");
  if (buffer.index >= stream_->buffers.size())
    throw SourceError(path_ + ": VIDIOC_DQBUF returned a buffer that was never allocated");
  stream_->held = static_cast<int>(buffer.index);
  return deliver(buffer, frame);
}

GrabStatus V4l2Camera::deliver(const v4l2_buffer& buffer, Frame& frame) {
  const std::uint64_t sequence = sequence_for(buffer.sequence);
  const bool complete = !(buffer.flags & V4L2_BUF_FLAG_ERROR) && buffer.bytesused >= minimum_image_bytes(negotiated_) &&
                        buffer.bytesused <= stream_->buffers[buffer.index].length;
  cv::Mat gray = complete ? luma_of(stream_->buffers[buffer.index].data, buffer.bytesused) : cv::Mat();
  if (gray.empty()) {
    ++counters_.corrupt;
    return GrabStatus::kCorrupt;
  }
  frame.cr = cr_;
  if (!field_luma_.empty()) {
    read_first_field(gray);
    frame.cr = field_cr_;
  }
  frame.gray = gray;
  frame.capture_time_ns = capture_time_ns(buffer);
  if (first_capture_ns_ < 0) first_capture_ns_ = frame.capture_time_ns;
  frame.sequence = sequence;
  frame.media_time_s = double(frame.capture_time_ns - first_capture_ns_) * 1e-9;
  frame.source = path_;
  ++counters_.delivered;
  return GrabStatus::kFrame;
}

std::uint64_t V4l2Camera::sequence_for(std::uint32_t driver_sequence) {
  if (stream_started_) {
    // Unsigned difference: the driver's 32-bit counter may wrap; a step back (a driver
    // bug) is not counted as a drop.
    const std::uint32_t gap = driver_sequence - expected_driver_sequence_;
    if (gap < (1u << 31)) {
      counters_.dropped += gap;
      next_sequence_ += gap;
    }
  }
  stream_started_ = true;
  expected_driver_sequence_ = driver_sequence + 1;
  return next_sequence_++;
}

void V4l2Camera::read_first_field(cv::Mat& gray) {
  // The two fields were captured half a frame period apart: a moving mouth shows in both,
  // combed together. Their first is read alone and brought back to the frame's height.
  to_frame_height(first_field(gray, negotiated_), field_luma_);
  gray = field_luma_;
  if (cr_.empty()) {
    field_cr_.release();
    return;
  }
  field_cr_.create(cr_.size(), CV_8UC1);  // allocates once per stream
  to_frame_height(first_field(cr_, negotiated_), field_cr_);
}

cv::Mat V4l2Camera::luma_of(const void* data, std::uint32_t bytes_used) {
  const int width = static_cast<int>(negotiated_.width);
  const int height = static_cast<int>(negotiated_.height);
  void* pixels = const_cast<void*>(data);  // cv::Mat has no const header; nothing writes to it
  switch (negotiated_.format) {
    case PixelFormat::kGrey: return cv::Mat(height, width, CV_8UC1, pixels, negotiated_.bytes_per_line);
    case PixelFormat::kNv12: {  // the Y plane, full size, then Cb Cr pairs at half size both ways
      const std::size_t luma_bytes = static_cast<std::size_t>(negotiated_.bytes_per_line) * height;
      cr_of_420(Chroma420::kPairs, static_cast<const std::uint8_t*>(data) + luma_bytes,
                chroma_stride(Chroma420::kPairs, negotiated_.bytes_per_line), width, height, cr_);
      return cv::Mat(height, width, CV_8UC1, pixels, negotiated_.bytes_per_line);
    }
    case PixelFormat::kYuyv:  // Y0 U Y1 V: luma is channel 0 of two-channel pixels, Cr channel 3 of pairs
      cv::extractChannel(cv::Mat(height, width, CV_8UC2, pixels, negotiated_.bytes_per_line), luma_, 0);
      cv::extractChannel(cv::Mat(height, width / 2, CV_8UC4, pixels, negotiated_.bytes_per_line), cr_, 3);
      return luma_;
    case PixelFormat::kMjpeg:
      // Not a JPEG: an empty image (never the previous frame's), which counts as corrupt.
      jpeg_->decode({static_cast<const std::uint8_t*>(data), bytes_used}, luma_, cr_);
      return luma_;
    case PixelFormat::kAuto: break;
  }
  throw std::logic_error("stream without a concrete pixel format");
}

GrabStatus V4l2Camera::fail(int error, const char* call) {
  if (error == EAGAIN || error == EINTR) return GrabStatus::kTimeout;
  if (is_disconnect(error)) {
    disconnect();
    return GrabStatus::kDisconnected;
  }
  throw SourceError(path_ + ": " + call + " failed: " + error_text(error));
}

void V4l2Camera::disconnect() {
  stream_.reset();
  ++counters_.disconnects;
  reconnect_backoff_.succeeded();  // the stream was up: retries start again at the first delay
  next_reconnect_ = Clock::now() + reconnect_backoff_.failed();
}

bool V4l2Camera::reconnect_before(Clock::time_point deadline) {
  if (next_reconnect_ > deadline) {
    // Waiting out the timeout keeps a caller that loops on grab() from spinning.
    std::this_thread::sleep_until(deadline);
    return false;
  }
  std::this_thread::sleep_until(next_reconnect_);
  try {
    start_stream();
  } catch (const SourceError& error) {
    reconnect_error_ = error.what();
    next_reconnect_ = Clock::now() + reconnect_backoff_.failed();
    return false;
  }
  reconnect_backoff_.succeeded();
  reconnect_error_.clear();
  ++counters_.reconnects;
  return true;
}

}  // namespace lipdrive
