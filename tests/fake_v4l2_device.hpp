// A fake V4L2 capture device behind the SystemCalls seam. It follows the kernel's rules
// (videodev2.h, videobuf2) closely enough that a driver passing against it does the right
// thing on hardware: formats are enumerated and adjusted, buffers are memory-mapped and
// cycle through queued -> done -> dequeued, misuse fails with the kernel's error codes and
// is recorded as a violation, and the device can vanish and come back.
//
// The test drives time: nothing is captured until it calls produce(); a poll() with no
// frame ready sleeps its whole timeout, like a stalled sensor.
#pragma once

#include "drivers/system_calls.hpp"

#include <linux/videodev2.h>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lipdrive::testing {

/// A gradient the luma checks can recognise: every pixel differs from its neighbours, and
/// `seed` makes consecutive frames differ.
cv::Mat test_pattern(cv::Size size, int seed);
/// The Cr plane the device sends with `luma` in `fourcc` (YUYV: per horizontal pair, NV12: per
/// 2x2 block, 255 - the luma of its first pixel); empty for formats without one (GREY, and
/// MJPEG, which the device encodes from the luma alone).
cv::Mat expected_cr(const cv::Mat& luma, std::uint32_t fourcc);

class FakeV4l2Device final : public SystemCalls {
 public:
  struct Config {
    std::string path = "/dev/video-fake";
    std::vector<std::uint32_t> formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_MJPEG};
    std::vector<cv::Size> sizes = {{320, 240}, {160, 120}};  // the first is the power-on size
    unsigned row_padding = 0;                                // bytes each row carries beyond its pixels (bytesperline)
    std::uint32_t capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
    std::vector<unsigned> frame_rates = {30, 15};  // the first is the power-on rate
    unsigned max_buffers = 8;
    bool monotonic_timestamps = true;
    /// A broken driver: every buffer carries this timestamp (flagged monotonic) instead of
    /// the capture time.
    std::optional<timeval> broken_timestamp;
    /// The controls it offers (VIDIOC_QUERYCTRL), each at its default_value after power-on.
    std::vector<v4l2_queryctrl> controls;
    /// How its frames hold their fields, whatever is asked for: an analogue video grabber
    /// answers V4L2_FIELD_INTERLACED (produce() takes the two fields already interleaved).
    std::uint32_t field = V4L2_FIELD_NONE;
  };

  struct Event {
    enum Kind { kQueue, kDequeue } kind;
    unsigned index;
  };

  explicit FakeV4l2Device(Config config);

  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* argument) override;
  void* mmap(void* address, std::size_t length, int protection, int flags, int fd, off_t offset) override;
  int munmap(void* address, std::size_t length) override;
  int poll(pollfd* fds, nfds_t count, int timeout_ms) override;

  // What the sensor does. Each capture takes a sequence number, even when it is lost.
  /// Captures `luma` (the current size) into the oldest queued buffer, encoded in the
  /// current format with expected_cr() as its Cr; false when no buffer was queued and the
  /// frame was lost.
  bool produce(const cv::Mat& luma);
  /// A capture the hardware flagged as broken (V4L2_BUF_FLAG_ERROR).
  bool produce_error_frame();
  /// A capture that ended early: bytesused is a fraction of a frame.
  bool produce_truncated_frame();
  /// Frames the sensor lost before reaching any buffer.
  void skip_frames(unsigned count);
  /// The next poll reports a frame although none is done (DQBUF then says EAGAIN).
  void spurious_wakeup();
  /// USB unplug: open fds go stale (ENODEV, POLLERR) and the node disappears (ENOENT).
  void unplug();
  /// The device enumerates again, in its power-on state.
  void replug();
  /// open() fails with `error` (0: opens): EACCES is a node udev has not given its group yet.
  void refuse_open(int error) { open_errno_ = error; }

  // What the test checks.
  cv::Size size() const { return {int(state_.width), int(state_.height)}; }
  std::uint32_t pixel_format() const { return state_.fourcc; }
  unsigned bytes_per_line() const { return state_.bytes_per_line; }
  bool streaming() const { return state_.streaming; }
  std::size_t open_fd_count() const { return fds_.size(); }
  std::size_t open_count() const { return open_count_; }  // calls, successful or not
  std::size_t mapping_count() const { return mappings_.size(); }
  std::int64_t last_timestamp_ns() const { return last_timestamp_ns_; }
  int last_poll_timeout_ms() const { return last_poll_timeout_ms_; }
  const std::vector<Event>& events() const { return events_; }
  /// A control's value; nullopt for one the device does not offer.
  std::optional<std::int32_t> control(std::uint32_t id) const;
  /// Calls that broke a V4L2 rule; a correct driver leaves this empty.
  const std::vector<std::string>& violations() const { return violations_; }

 private:
  enum class BufferState { kUser, kQueued, kDone };
  struct Buffer {
    std::shared_ptr<std::vector<std::uint8_t>> memory;  // shared with live mappings
    std::uint32_t offset = 0;
    BufferState state = BufferState::kUser;
    std::uint32_t bytes_used = 0;
    std::uint32_t flags = 0;
    std::uint32_t sequence = 0;
    timeval timestamp{};
  };
  struct DeviceState {  // what one enumeration of the device holds
    std::uint32_t fourcc = 0;
    unsigned width = 0, height = 0, bytes_per_line = 0, image_size = 0;
    unsigned frame_rate = 0;
    std::vector<Buffer> buffers;
    std::deque<unsigned> queued, done;
    bool streaming = false;
    int owner_fd = -1;  // the fd that allocated the buffers
    std::uint32_t next_sequence = 0;
    std::map<std::uint32_t, std::int32_t> controls;  // id -> value
  };
  struct OpenFile {
    unsigned generation;
    bool non_blocking;
  };
  struct Mapping {
    std::size_t length;
    std::shared_ptr<std::vector<std::uint8_t>> memory;
  };

  DeviceState power_on_state() const;
  void adjust_format(v4l2_pix_format& pix) const;
  int fail(int error, const std::string& violation = {});
  void* fail_mapping(int error, const std::string& violation = {});
  int query_capability(v4l2_capability& capability) const;
  int enumerate_format(v4l2_fmtdesc& description);
  int get_format(v4l2_format& format);
  int set_format(v4l2_format& format);
  int get_parameters(v4l2_streamparm& parameters);
  int set_parameters(v4l2_streamparm& parameters);
  int request_buffers(int fd, v4l2_requestbuffers& request);
  int query_buffer(v4l2_buffer& buffer);
  int queue_buffer(v4l2_buffer& buffer);
  int dequeue_buffer(int fd, v4l2_buffer& buffer);
  int stream_on(const v4l2_buf_type& type);
  int query_control(v4l2_queryctrl& query);
  int get_control(v4l2_control& control);
  int set_control(v4l2_control& control);
  int stream_off(const v4l2_buf_type& type);
  void release_buffers();
  void describe(unsigned index, v4l2_buffer& buffer) const;
  bool buffers_mapped() const;
  Buffer* next_capture();
  void complete(Buffer& buffer, std::uint32_t bytes_used, std::uint32_t flags);
  void encode(const cv::Mat& luma, std::vector<std::uint8_t>& memory) const;

  Config config_;
  DeviceState state_;
  bool plugged_ = true;
  int open_errno_ = 0;
  unsigned generation_ = 0;  // bumped by unplug: fds of an older generation are stale
  int next_fd_ = 1000;
  std::size_t open_count_ = 0;
  std::map<int, OpenFile> fds_;
  std::map<const void*, Mapping> mappings_;
  bool spurious_wakeup_ = false;
  std::int64_t last_timestamp_ns_ = 0;
  int last_poll_timeout_ms_ = 0;
  std::vector<Event> events_;
  std::vector<std::string> violations_;
};

}  // namespace lipdrive::testing
