#include "tests/fake_v4l2_device.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <time.h>

#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <thread>

namespace lipdrive::testing {
namespace {

constexpr std::uint8_t kPaddingByte = 0xEE;  // row padding: a stride bug shows up as this value
constexpr std::uint32_t kPageSize = 4096;

bool is_packed_yuv(std::uint32_t fourcc) { return fourcc == V4L2_PIX_FMT_YUYV; }
bool is_compressed(std::uint32_t fourcc) { return fourcc == V4L2_PIX_FMT_MJPEG; }

std::uint32_t page_aligned(std::uint32_t bytes) { return (bytes + kPageSize - 1) / kPageSize * kPageSize; }

}  // namespace

cv::Mat test_pattern(cv::Size size, int seed) {
  cv::Mat pattern(size, CV_8UC1);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) pattern.at<std::uint8_t>(y, x) = std::uint8_t(x + 3 * y + 17 * seed);
  return pattern;
}

FakeV4l2Device::FakeV4l2Device(Config config) : config_(std::move(config)), state_(power_on_state()) {}

FakeV4l2Device::DeviceState FakeV4l2Device::power_on_state() const {
  DeviceState state;
  v4l2_pix_format pix{};
  pix.pixelformat = config_.formats.at(0);
  pix.width = unsigned(config_.sizes.at(0).width);
  pix.height = unsigned(config_.sizes.at(0).height);
  adjust_format(pix);
  state.fourcc = pix.pixelformat;
  state.width = pix.width;
  state.height = pix.height;
  state.bytes_per_line = pix.bytesperline;
  state.image_size = pix.sizeimage;
  state.frame_rate = config_.frame_rates.at(0);
  for (const v4l2_queryctrl& control : config_.controls) state.controls[control.id] = control.default_value;
  return state;
}

/// What drivers do with VIDIOC_S_FMT: an unsupported format becomes the first supported
/// one, the size snaps to the nearest supported size, and the driver picks the stride.
void FakeV4l2Device::adjust_format(v4l2_pix_format& pix) const {
  if (std::ranges::find(config_.formats, pix.pixelformat) == config_.formats.end())
    pix.pixelformat = config_.formats.front();
  const auto distance = [&](cv::Size size) {
    return std::abs(size.width - int(pix.width)) + std::abs(size.height - int(pix.height));
  };
  const cv::Size nearest =
      *std::ranges::min_element(config_.sizes, [&](cv::Size a, cv::Size b) { return distance(a) < distance(b); });
  pix.width = unsigned(nearest.width);
  pix.height = unsigned(nearest.height);
  pix.field = config_.field;
  if (is_compressed(pix.pixelformat)) {
    pix.bytesperline = 0;
    pix.sizeimage = pix.width * pix.height;  // worst case for a JPEG of this size
  } else {
    pix.bytesperline = pix.width * (is_packed_yuv(pix.pixelformat) ? 2 : 1) + config_.row_padding;
    pix.sizeimage = pix.bytesperline * pix.height * (pix.pixelformat == V4L2_PIX_FMT_NV12 ? 3 : 2) / 2;
  }
}

int FakeV4l2Device::fail(int error, const std::string& violation) {
  if (!violation.empty()) violations_.push_back(violation);
  errno = error;
  return -1;
}

void* FakeV4l2Device::fail_mapping(int error, const std::string& violation) {
  fail(error, violation);
  return MAP_FAILED;
}

int FakeV4l2Device::open(const char* path, int flags) {
  ++open_count_;
  if (!plugged_ || path != config_.path) return fail(ENOENT);
  if (open_errno_ != 0) return fail(open_errno_);
  const int fd = next_fd_++;
  fds_[fd] = {generation_, (flags & O_NONBLOCK) != 0};
  return fd;
}

int FakeV4l2Device::close(int fd) {
  const auto file = fds_.find(fd);
  if (file == fds_.end()) return fail(EBADF, "close of an fd that is not open");
  const bool current = file->second.generation == generation_;
  fds_.erase(file);
  // videobuf2 stops the stream and frees the buffers when their owner closes; memory that
  // is still mapped lives on until munmap.
  if (current && state_.owner_fd == fd) release_buffers();
  return 0;
}

int FakeV4l2Device::ioctl(int fd, unsigned long request, void* argument) {
  const auto file = fds_.find(fd);
  if (file == fds_.end()) return fail(EBADF, "ioctl on an fd that is not open");
  if (!plugged_ || file->second.generation != generation_) return fail(ENODEV);
  switch (request) {
    case VIDIOC_QUERYCAP: return query_capability(*static_cast<v4l2_capability*>(argument));
    case VIDIOC_ENUM_FMT: return enumerate_format(*static_cast<v4l2_fmtdesc*>(argument));
    case VIDIOC_G_FMT: return get_format(*static_cast<v4l2_format*>(argument));
    case VIDIOC_S_FMT: return set_format(*static_cast<v4l2_format*>(argument));
    case VIDIOC_G_PARM: return get_parameters(*static_cast<v4l2_streamparm*>(argument));
    case VIDIOC_S_PARM: return set_parameters(*static_cast<v4l2_streamparm*>(argument));
    case VIDIOC_REQBUFS: return request_buffers(fd, *static_cast<v4l2_requestbuffers*>(argument));
    case VIDIOC_QUERYBUF: return query_buffer(*static_cast<v4l2_buffer*>(argument));
    case VIDIOC_QBUF: return queue_buffer(*static_cast<v4l2_buffer*>(argument));
    case VIDIOC_DQBUF: return dequeue_buffer(fd, *static_cast<v4l2_buffer*>(argument));
    case VIDIOC_STREAMON: return stream_on(*static_cast<v4l2_buf_type*>(argument));
    case VIDIOC_STREAMOFF: return stream_off(*static_cast<v4l2_buf_type*>(argument));
    case VIDIOC_QUERYCTRL: return query_control(*static_cast<v4l2_queryctrl*>(argument));
    case VIDIOC_G_CTRL: return get_control(*static_cast<v4l2_control*>(argument));
    case VIDIOC_S_CTRL: return set_control(*static_cast<v4l2_control*>(argument));
    default: return fail(ENOTTY);
  }
}

int FakeV4l2Device::query_capability(v4l2_capability& capability) const {
  capability = {};
  std::strncpy(reinterpret_cast<char*>(capability.driver), "fake", sizeof capability.driver - 1);
  std::strncpy(reinterpret_cast<char*>(capability.card), "Fake V4L2 camera", sizeof capability.card - 1);
  std::strncpy(reinterpret_cast<char*>(capability.bus_info), "platform:fake", sizeof capability.bus_info - 1);
  capability.capabilities = config_.capabilities | V4L2_CAP_DEVICE_CAPS;
  capability.device_caps = config_.capabilities;
  return 0;
}

int FakeV4l2Device::enumerate_format(v4l2_fmtdesc& description) {
  if (description.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || description.index >= config_.formats.size())
    return fail(EINVAL);
  const std::uint32_t index = description.index;
  description = {};
  description.index = index;
  description.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  description.pixelformat = config_.formats[index];
  description.flags = is_compressed(description.pixelformat) ? V4L2_FMT_FLAG_COMPRESSED : 0;
  return 0;
}

int FakeV4l2Device::get_format(v4l2_format& format) {
  if (format.type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL, "G_FMT of a non-capture type");
  v4l2_pix_format& pix = format.fmt.pix;
  pix = {};
  pix.pixelformat = state_.fourcc;
  pix.width = state_.width;
  pix.height = state_.height;
  pix.bytesperline = state_.bytes_per_line;
  pix.sizeimage = state_.image_size;
  pix.field = config_.field;
  return 0;
}

int FakeV4l2Device::set_format(v4l2_format& format) {
  if (format.type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL, "S_FMT of a non-capture type");
  if (!state_.buffers.empty()) return fail(EBUSY, "S_FMT while buffers are allocated");
  adjust_format(format.fmt.pix);
  state_.fourcc = format.fmt.pix.pixelformat;
  state_.width = format.fmt.pix.width;
  state_.height = format.fmt.pix.height;
  state_.bytes_per_line = format.fmt.pix.bytesperline;
  state_.image_size = format.fmt.pix.sizeimage;
  return 0;
}

int FakeV4l2Device::get_parameters(v4l2_streamparm& parameters) {
  if (parameters.type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL, "G_PARM of a non-capture type");
  parameters.parm.capture = {};
  parameters.parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
  parameters.parm.capture.timeperframe = {1, state_.frame_rate};
  return 0;
}

int FakeV4l2Device::set_parameters(v4l2_streamparm& parameters) {
  if (parameters.type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL, "S_PARM of a non-capture type");
  const v4l2_fract interval = parameters.parm.capture.timeperframe;
  if (interval.numerator != 0 && interval.denominator != 0) {
    const double wanted = double(interval.denominator) / interval.numerator;
    state_.frame_rate = *std::ranges::min_element(
        config_.frame_rates, [&](unsigned a, unsigned b) { return std::abs(a - wanted) < std::abs(b - wanted); });
  }
  return get_parameters(parameters);
}

bool FakeV4l2Device::buffers_mapped() const {
  return std::ranges::any_of(state_.buffers, [](const Buffer& buffer) { return buffer.memory.use_count() > 1; });
}

int FakeV4l2Device::request_buffers(int fd, v4l2_requestbuffers& request) {
  if (request.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || request.memory != V4L2_MEMORY_MMAP)
    return fail(EINVAL, "REQBUFS with a type or memory other than capture/MMAP");
  if (state_.owner_fd != -1 && state_.owner_fd != fd) return fail(EBUSY, "REQBUFS on a device another fd owns");
  if (state_.streaming) return fail(EBUSY, "REQBUFS while streaming");
  if (buffers_mapped()) return fail(EBUSY, "REQBUFS while buffers are still mapped");
  release_buffers();
  if (request.count == 0) return 0;
  request.count = std::clamp(request.count, 2u, config_.max_buffers);
  std::uint32_t offset = 0;
  for (unsigned index = 0; index < request.count; ++index) {
    Buffer buffer;
    buffer.memory = std::make_shared<std::vector<std::uint8_t>>(page_aligned(state_.image_size));
    buffer.offset = offset;
    offset += std::uint32_t(buffer.memory->size());
    state_.buffers.push_back(std::move(buffer));
  }
  state_.owner_fd = fd;
  return 0;
}

void FakeV4l2Device::release_buffers() {
  state_.streaming = false;
  state_.buffers.clear();
  state_.queued.clear();
  state_.done.clear();
  state_.owner_fd = -1;
}

void FakeV4l2Device::describe(unsigned index, v4l2_buffer& buffer) const {
  const Buffer& source = state_.buffers[index];
  buffer = {};
  buffer.index = index;
  buffer.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buffer.memory = V4L2_MEMORY_MMAP;
  buffer.length = std::uint32_t(source.memory->size());
  buffer.m.offset = source.offset;
  buffer.bytesused = source.bytes_used;
  buffer.sequence = source.sequence;
  buffer.timestamp = source.timestamp;
  buffer.field = config_.field;
  buffer.flags = source.flags | (source.state == BufferState::kQueued ? V4L2_BUF_FLAG_QUEUED : 0) |
                 (source.state == BufferState::kDone ? V4L2_BUF_FLAG_DONE : 0);
}

int FakeV4l2Device::query_buffer(v4l2_buffer& buffer) {
  if (buffer.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buffer.index >= state_.buffers.size())
    return fail(EINVAL, "QUERYBUF of a buffer that does not exist");
  describe(buffer.index, buffer);
  return 0;
}

int FakeV4l2Device::queue_buffer(v4l2_buffer& buffer) {
  if (buffer.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buffer.memory != V4L2_MEMORY_MMAP ||
      buffer.index >= state_.buffers.size())
    return fail(EINVAL, "QBUF of a buffer that does not exist");
  if (state_.buffers[buffer.index].state != BufferState::kUser)
    return fail(EINVAL, "QBUF of buffer " + std::to_string(buffer.index) + ", which is already queued");
  state_.buffers[buffer.index].state = BufferState::kQueued;
  state_.queued.push_back(buffer.index);
  events_.push_back({Event::kQueue, buffer.index});
  describe(buffer.index, buffer);
  return 0;
}

int FakeV4l2Device::dequeue_buffer(int fd, v4l2_buffer& buffer) {
  if (buffer.type != V4L2_BUF_TYPE_VIDEO_CAPTURE || buffer.memory != V4L2_MEMORY_MMAP)
    return fail(EINVAL, "DQBUF with a type or memory other than capture/MMAP");
  if (!state_.streaming) return fail(EINVAL, "DQBUF before STREAMON");
  if (state_.done.empty())
    return fail(EAGAIN, fds_.at(fd).non_blocking ? "" : "DQBUF would block forever (fd is blocking)");
  const unsigned index = state_.done.front();
  state_.done.pop_front();
  state_.buffers[index].state = BufferState::kUser;
  events_.push_back({Event::kDequeue, index});
  describe(index, buffer);
  return 0;
}

int FakeV4l2Device::stream_on(const v4l2_buf_type& type) {
  if (type != V4L2_BUF_TYPE_VIDEO_CAPTURE || state_.buffers.empty()) return fail(EINVAL, "STREAMON without buffers");
  state_.streaming = true;
  return 0;
}

int FakeV4l2Device::stream_off(const v4l2_buf_type& type) {
  if (type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL, "STREAMOFF of a non-capture type");
  // Like videobuf2: every buffer returns to the application, queued or done.
  state_.streaming = false;
  for (Buffer& buffer : state_.buffers) buffer.state = BufferState::kUser;
  state_.queued.clear();
  state_.done.clear();
  return 0;
}

void* FakeV4l2Device::mmap(void* address, std::size_t length, int protection, int flags, int fd, off_t offset) {
  const auto file = fds_.find(fd);
  if (file == fds_.end()) return fail_mapping(EBADF, "mmap of an fd that is not open");
  if (!plugged_ || file->second.generation != generation_) return fail_mapping(ENODEV);
  if (address != nullptr || !(flags & MAP_SHARED) || !(protection & PROT_READ))
    return fail_mapping(EINVAL, "mmap of a buffer must be shared, readable and placed by the kernel");
  const auto buffer = std::ranges::find_if(
      state_.buffers, [&](const Buffer& candidate) { return candidate.offset == std::uint32_t(offset); });
  if (buffer == state_.buffers.end() || length > buffer->memory->size())
    return fail_mapping(EINVAL, "mmap at an offset or length QUERYBUF did not give");
  if (mappings_.contains(buffer->memory->data()))
    return fail_mapping(EINVAL, "buffer at offset " + std::to_string(offset) + " mapped twice");
  mappings_[buffer->memory->data()] = {length, buffer->memory};
  return buffer->memory->data();
}

int FakeV4l2Device::munmap(void* address, std::size_t length) {
  const auto mapping = mappings_.find(address);
  if (mapping == mappings_.end() || mapping->second.length != length)
    return fail(EINVAL, "munmap of memory that was not mapped with this length");
  mappings_.erase(mapping);
  return 0;
}

int FakeV4l2Device::poll(pollfd* fds, nfds_t count, int timeout_ms) {
  if (count != 1) return fail(EINVAL, "poll of other than one fd");
  last_poll_timeout_ms_ = timeout_ms;
  pollfd& target = fds[0];
  const auto file = fds_.find(target.fd);
  if (file == fds_.end()) {
    target.revents = POLLNVAL;
    return 1;
  }
  // videobuf2 reports POLLERR when it could never wake up: device gone, not streaming, or
  // nothing queued for the hardware to fill.
  const bool hopeless = !plugged_ || file->second.generation != generation_ || !state_.streaming ||
                        (state_.queued.empty() && state_.done.empty());
  if (hopeless) {
    target.revents = POLLERR;
    return 1;
  }
  if (!state_.done.empty() || spurious_wakeup_) {
    spurious_wakeup_ = false;
    target.revents = short(target.events & (POLLIN | POLLRDNORM));
    return 1;
  }
  if (timeout_ms < 0) return fail(EINVAL, "poll without a timeout on a stalled device would hang");
  std::this_thread::sleep_for(std::chrono::milliseconds(timeout_ms));
  target.revents = 0;
  return 0;
}

FakeV4l2Device::Buffer* FakeV4l2Device::next_capture() {
  const std::uint32_t sequence = state_.next_sequence++;
  if (!state_.streaming || state_.queued.empty()) return nullptr;
  Buffer& buffer = state_.buffers[state_.queued.front()];
  state_.queued.pop_front();
  buffer.sequence = sequence;
  return &buffer;
}

void FakeV4l2Device::complete(Buffer& buffer, std::uint32_t bytes_used, std::uint32_t flags) {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  // A driver without monotonic timestamps: the value means nothing to CLOCK_MONOTONIC.
  if (!config_.monotonic_timestamps) now = {1'000'000'000 + now.tv_sec, now.tv_nsec};
  buffer.timestamp = {now.tv_sec, now.tv_nsec / 1000};
  last_timestamp_ns_ = std::int64_t{now.tv_sec} * 1'000'000'000 + std::int64_t{now.tv_nsec / 1000} * 1000;
  if (config_.broken_timestamp) buffer.timestamp = *config_.broken_timestamp;
  buffer.bytes_used = bytes_used;
  buffer.flags =
      flags | (config_.monotonic_timestamps ? V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC : V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN);
  buffer.state = BufferState::kDone;
  const auto index = unsigned(&buffer - state_.buffers.data());
  state_.done.push_back(index);
}

void FakeV4l2Device::encode(const cv::Mat& luma, std::vector<std::uint8_t>& memory) const {
  if (luma.type() != CV_8UC1 || luma.cols != int(state_.width) || luma.rows != int(state_.height))
    throw std::invalid_argument("produce(): the frame must be 8-bit and the negotiated size");
  std::ranges::fill(memory, kPaddingByte);
  const unsigned stride = state_.bytes_per_line;
  for (int y = 0; y < luma.rows; ++y) {
    std::uint8_t* row = memory.data() + y * stride;
    for (int x = 0; x < luma.cols; ++x) {
      if (is_packed_yuv(state_.fourcc)) {
        row[2 * x] = luma.at<std::uint8_t>(y, x);
        // U (even pixels), V (odd): U fixed, V the pair's expected_cr
        row[2 * x + 1] = x % 2 ? static_cast<std::uint8_t>(255 - luma.at<std::uint8_t>(y, x - 1)) : 0xC0;
      } else {
        row[x] = luma.at<std::uint8_t>(y, x);
      }
    }
  }
  if (state_.fourcc == V4L2_PIX_FMT_NV12)  // U V pairs at half size both ways, after the Y plane
    for (int y = 0; y < luma.rows / 2; ++y) {
      std::uint8_t* row = memory.data() + (luma.rows + y) * stride;
      for (int x = 0; x < luma.cols / 2; ++x) {
        row[2 * x] = 0xC0;
        row[2 * x + 1] = static_cast<std::uint8_t>(255 - luma.at<std::uint8_t>(2 * y, 2 * x));
      }
    }
}

cv::Mat expected_cr(const cv::Mat& luma, std::uint32_t fourcc) {
  if (fourcc != V4L2_PIX_FMT_YUYV && fourcc != V4L2_PIX_FMT_NV12) return {};
  const int step_y = fourcc == V4L2_PIX_FMT_NV12 ? 2 : 1;
  cv::Mat cr(luma.rows / step_y, luma.cols / 2, CV_8UC1);
  for (int y = 0; y < cr.rows; ++y)
    for (int x = 0; x < cr.cols; ++x) cr.at<std::uint8_t>(y, x) = 255 - luma.at<std::uint8_t>(step_y * y, 2 * x);
  return cr;
}

bool FakeV4l2Device::produce(const cv::Mat& luma) {
  Buffer* buffer = next_capture();
  if (buffer == nullptr) return false;
  if (!is_compressed(state_.fourcc)) {
    encode(luma, *buffer->memory);
    complete(*buffer, state_.image_size, 0);
    return true;
  }
  if (luma.cols != int(state_.width) || luma.rows != int(state_.height))
    throw std::invalid_argument("produce(): the frame must be the negotiated size");
  std::vector<std::uint8_t> jpeg;
  cv::imencode(".jpg", luma, jpeg, {cv::IMWRITE_JPEG_QUALITY, 100});
  if (jpeg.size() > buffer->memory->size()) throw std::logic_error("produce(): JPEG larger than the buffer");
  std::ranges::copy(jpeg, buffer->memory->begin());
  complete(*buffer, std::uint32_t(jpeg.size()), 0);
  return true;
}

bool FakeV4l2Device::produce_error_frame() {
  Buffer* buffer = next_capture();
  if (buffer == nullptr) return false;
  complete(*buffer, state_.image_size, V4L2_BUF_FLAG_ERROR);
  return true;
}

bool FakeV4l2Device::produce_truncated_frame() {
  Buffer* buffer = next_capture();
  if (buffer == nullptr) return false;
  complete(*buffer, state_.image_size / 3, 0);
  return true;
}

void FakeV4l2Device::skip_frames(unsigned count) { state_.next_sequence += count; }

void FakeV4l2Device::spurious_wakeup() { spurious_wakeup_ = true; }

void FakeV4l2Device::unplug() {
  plugged_ = false;
  ++generation_;
  state_ = power_on_state();  // mapped memory survives through the mappings' shared_ptrs
}

void FakeV4l2Device::replug() { plugged_ = true; }

int FakeV4l2Device::query_control(v4l2_queryctrl& query) {
  const auto offered = std::ranges::find(config_.controls, query.id, &v4l2_queryctrl::id);
  // The kernel's answer for a control the device lacks: asking is no misuse.
  if (offered == config_.controls.end()) return fail(EINVAL);
  query = *offered;
  return 0;
}

int FakeV4l2Device::get_control(v4l2_control& control) {
  const auto value = state_.controls.find(control.id);
  if (value == state_.controls.end()) return fail(EINVAL);
  control.value = value->second;
  return 0;
}

/// Strict where the kernel clamps integer controls: a driver should have read the range first.
int FakeV4l2Device::set_control(v4l2_control& control) {
  const auto offered = std::ranges::find(config_.controls, control.id, &v4l2_queryctrl::id);
  if (offered == config_.controls.end()) return fail(EINVAL, "VIDIOC_S_CTRL of a control the device does not offer");
  if (control.value < offered->minimum || control.value > offered->maximum)
    return fail(ERANGE, "VIDIOC_S_CTRL outside the range VIDIOC_QUERYCTRL reports");
  state_.controls[control.id] = control.value;
  return 0;
}

std::optional<std::int32_t> FakeV4l2Device::control(std::uint32_t id) const {
  const auto value = state_.controls.find(id);
  return value == state_.controls.end() ? std::nullopt : std::optional(value->second);
}

}  // namespace lipdrive::testing
