#include "drivers/libcamera_camera.hpp"

#include "core/backoff.hpp"
#include "drivers/chroma_420.hpp"

#include <sys/mman.h>

#include <libcamera/libcamera.h>
#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <optional>
#include <system_error>
#include <thread>
#include <utility>
#include <vector>

namespace lipdrive {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr auto kReconnectInitial = 100ms;
constexpr auto kReconnectMax = 5000ms;

/// Formats whose first plane is the full-resolution luma, in order of preference.
const std::array kLumaFirst = {libcamera::formats::YUV420, libcamera::formats::NV12, libcamera::formats::YVU420,
                               libcamera::formats::NV21, libcamera::formats::R8};

bool is_luma_first(const libcamera::PixelFormat& format) {
  return std::ranges::find(kLumaFirst, format) != kLumaFirst.end();
}

/// Where a luma-first format keeps its Cr; none in R8.
std::optional<Chroma420> chroma_of(const libcamera::PixelFormat& format) {
  if (format == libcamera::formats::YUV420) return Chroma420::kPlanes;
  if (format == libcamera::formats::YVU420) return Chroma420::kPlanesCrFirst;
  if (format == libcamera::formats::NV12) return Chroma420::kPairs;
  if (format == libcamera::formats::NV21) return Chroma420::kPairsCrFirst;
  return std::nullopt;
}

/// libcamera returns negated errno values.
std::string error_text(int negative_errno) { return std::generic_category().message(-negative_errno); }

/// A hold on the process's CameraManager, started while anyone holds it: libcamera allows
/// a single CameraManager per process, and a front and a side camera must share it. The
/// count and the manager are guarded by one mutex, so the last holder has stopped and
/// destroyed the manager before the next one can create it.
class ManagerLease {
 public:
  ManagerLease() {
    std::lock_guard lock(mutex_);
    if (users_ == 0) {
      auto manager = std::make_unique<libcamera::CameraManager>();
      if (const int error = manager->start(); error < 0)
        throw SourceError("libcamera: cannot start the camera manager: " + error_text(error));
      manager_ = std::move(manager);
    }
    ++users_;
  }
  ~ManagerLease() {
    std::lock_guard lock(mutex_);
    if (--users_ == 0) {
      manager_->stop();
      manager_.reset();
    }
  }
  ManagerLease(const ManagerLease&) = delete;
  ManagerLease& operator=(const ManagerLease&) = delete;

  libcamera::CameraManager& manager() const { return *manager_; }

 private:
  static inline std::mutex mutex_;
  static inline std::unique_ptr<libcamera::CameraManager> manager_;
  static inline int users_ = 0;
};

/// A configured, streaming camera: acquired, its buffers allocated and mapped, every request
/// queued. Built step by step by open(), so a failure half-way releases exactly what was
/// taken (the destructor undoes the steps in reverse).
///
/// Thread model: the owner thread makes every call; libcamera's thread calls only the two
/// slots, which touch nothing but `completed_` and `gone_` under `mutex_`.
class Session {
 public:
  static std::unique_ptr<Session> open(std::shared_ptr<libcamera::Camera> camera, const LibcameraOptions& options) {
    std::unique_ptr<Session> session(new Session(std::move(camera)));
    session->acquire();
    session->configure(options);
    session->map_buffers();
    session->start(options.frame_rate, options.exposure_us);
    return session;
  }

  ~Session() {
    // stop() completes the requests in flight as cancelled (through the slot) and ends the
    // callbacks for requests; after it no buffer is in use and the slots can go.
    if (started_) camera_->stop();
    // libcamera's signals are not guarded against disconnecting while they emit; after stop()
    // only a hot-unplug at this very moment could still emit `disconnected` (not guarded).
    if (connected_) {
      camera_->requestCompleted.disconnect(this);
      camera_->disconnected.disconnect(this);
    }
    requests_.clear();
    for (const Mapping& mapping : mappings_) munmap(mapping.base, mapping.length);
    allocator_.reset();  // frees the buffers
    if (acquired_) camera_->release();
  }
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  /// The next completed request, oldest first; nullptr at `deadline` or once the camera is
  /// gone.
  libcamera::Request* wait_completed(Clock::time_point deadline) {
    std::unique_lock lock(mutex_);
    completed_cv_.wait_until(lock, deadline, [&] { return gone_ || !completed_.empty(); });
    if (gone_ || completed_.empty()) return nullptr;
    libcamera::Request* request = completed_.front();
    completed_.erase(completed_.begin());
    return request;
  }

  bool gone() const {
    std::lock_guard lock(mutex_);
    return gone_;
  }

  /// Hands a completed request back with its buffer; false if the camera refused it.
  bool requeue(libcamera::Request* request) {
    request->reuse(libcamera::Request::ReuseBuffers);
    return camera_->queueRequest(request) == 0;
  }

  const libcamera::FrameMetadata& metadata(const libcamera::Request& request) const {
    return request.findBuffer(stream_)->metadata();
  }
  /// Wraps the luma plane of a completed request's buffer (no copy).
  cv::Mat luma(const libcamera::Request& request) const {
    return cv::Mat(static_cast<int>(height_), static_cast<int>(width_), CV_8UC1,
                   const_cast<std::uint8_t*>(planes_[request.cookie()].luma), stride_);
  }
  /// Its Cr at half the width and height: wrapped, or gathered from Cb Cr pairs into the
  /// session's own plane; empty without colour (R8).
  cv::Mat cr(const libcamera::Request& request) {
    const std::uint8_t* plane = planes_[request.cookie()].cr;
    if (!chroma_ || plane == nullptr) return {};
    return cr_of_420(*chroma_, plane, chroma_stride(*chroma_, stride_), static_cast<int>(width_),
                     static_cast<int>(height_), gathered_cr_);
  }
  double frame_rate() const { return frame_rate_; }

 private:
  struct Mapping {
    void* base;
    std::size_t length;
  };
  /// Where a buffer's planes are mapped.
  struct BufferPlanes {
    const std::uint8_t* luma = nullptr;
    const std::uint8_t* cr = nullptr;  // null without colour
  };

  explicit Session(std::shared_ptr<libcamera::Camera> camera) : camera_(std::move(camera)) {}

  [[noreturn]] void fail(const std::string& reason) const {
    throw SourceError("libcamera " + camera_->id() + ": " + reason);
  }

  void acquire() {
    if (const int error = camera_->acquire(); error < 0)
      fail(error == -EBUSY ? "busy (in use by another process or source)" : "cannot acquire: " + error_text(error));
    acquired_ = true;
  }

  void configure(const LibcameraOptions& options) {
    // libcamera API: 0.0.3 takes a StreamRoles vector, 0.1+ a Span<const StreamRole>; a
    // std::vector converts to both.
    const std::vector<libcamera::StreamRole> roles{libcamera::StreamRole::Viewfinder};
    const std::unique_ptr<libcamera::CameraConfiguration> config = camera_->generateConfiguration(roles);
    if (!config || config->empty()) fail("offers no viewfinder stream");
    libcamera::StreamConfiguration& stream = config->at(0);

    const std::vector<libcamera::PixelFormat> offered = stream.formats().pixelformats();
    const auto chosen = std::ranges::find_if(kLumaFirst, [&](const libcamera::PixelFormat& format) {
      return std::ranges::find(offered, format) != offered.end();
    });
    if (chosen == kLumaFirst.end()) {
      std::string list;
      for (const auto& format : offered) list += (list.empty() ? "" : ", ") + format.toString();
      fail("offers none of YUV420, NV12, YVU420, NV21, R8 (offers: " + (list.empty() ? "none" : list) + ")");
    }
    stream.pixelFormat = *chosen;
    if (options.width) stream.size.width = options.width;
    if (options.height) stream.size.height = options.height;

    const std::string requested = stream.toString();
    switch (config->validate()) {
      case libcamera::CameraConfiguration::Invalid: fail("cannot stream " + requested);
      case libcamera::CameraConfiguration::Adjusted:
        spdlog::info("libcamera {}: asked for {}, streams {}", camera_->id(), requested, stream.toString());
        break;
      case libcamera::CameraConfiguration::Valid: break;
    }
    if (!is_luma_first(stream.pixelFormat))
      fail("adjusted the format to " + stream.pixelFormat.toString() + ", which has no luma plane first");
    if (const int error = camera_->configure(config.get()); error < 0)
      fail("cannot configure " + stream.toString() + ": " + error_text(error));

    stream_ = stream.stream();
    width_ = stream.size.width;
    height_ = stream.size.height;
    stride_ = stream.stride;
    chroma_ = chroma_of(stream.pixelFormat);
  }

  void map_buffers() {
    allocator_ = std::make_unique<libcamera::FrameBufferAllocator>(camera_);
    if (const int error = allocator_->allocate(stream_); error < 0)
      fail("cannot allocate buffers: " + error_text(error));
    for (const std::unique_ptr<libcamera::FrameBuffer>& buffer : allocator_->buffers(stream_)) {
      // The luma plane is the first.
      const libcamera::FrameBuffer::Plane& luma = buffer->planes().front();
      if (luma.length < std::size_t{stride_} * height_) fail("buffer luma plane shorter than stride x height");
      planes_.push_back({map(luma), chroma_ ? map_cr(*buffer) : nullptr});

      // The cookie is the buffer's index in planes_.
      std::unique_ptr<libcamera::Request> request = camera_->createRequest(planes_.size() - 1);
      if (!request) fail("cannot create a request");
      if (const int error = request->addBuffer(stream_, buffer.get()); error < 0)
        fail("cannot add a buffer to a request: " + error_text(error));
      requests_.push_back(std::move(request));
    }
    // Every request is in flight or completed at most once: push_back never reallocates
    // on libcamera's thread.
    completed_.reserve(requests_.size());
    if (chroma_) gathered_cr_.create(static_cast<int>(height_ / 2), static_cast<int>(width_ / 2), CV_8UC1);
  }

  /// Maps a plane readable and returns its first byte. A plane may share its dmabuf with the
  /// others at an offset, and mmap needs a page-aligned file offset, so the map starts at 0.
  const std::uint8_t* map(const libcamera::FrameBuffer::Plane& plane) {
    if (plane.offset == libcamera::FrameBuffer::Plane::kInvalidOffset) fail("buffer plane without an offset");
    const std::size_t length = std::size_t{plane.offset} + plane.length;
    void* base = mmap(nullptr, length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
    if (base == MAP_FAILED) fail("cannot map a buffer: " + error_text(-errno));
    mappings_.push_back({base, length});
    return static_cast<const std::uint8_t*>(base) + plane.offset;
  }

  /// The buffer's Cr plane (or plane of pairs), mapped. Null, with a warning, when the
  /// buffer's planes do not hold it (the lip contact then reads the luma alone).
  const std::uint8_t* map_cr(const libcamera::FrameBuffer& buffer) {
    std::vector<BufferBytes> planes;
    for (const libcamera::FrameBuffer::Plane& plane : buffer.planes()) {
      if (plane.offset == libcamera::FrameBuffer::Plane::kInvalidOffset)
        return no_colour("a buffer plane without an offset");
      planes.push_back({planes.size(), plane.offset, plane.length});
    }
    const std::optional<BufferBytes> cr =
        locate_cr(*chroma_, planes, stride_, static_cast<int>(width_), static_cast<int>(height_));
    if (!cr) return no_colour("its buffers do not hold the format's chroma plane");
    libcamera::FrameBuffer::Plane plane = buffer.planes()[cr->plane];
    plane.offset = static_cast<unsigned>(cr->offset);
    plane.length = static_cast<unsigned>(cr->length);
    return map(plane);
  }

  const std::uint8_t* no_colour(const char* reason) {
    spdlog::warn("libcamera {}: {}: the lip contact reads the luma alone", camera_->id(), reason);
    chroma_.reset();
    return nullptr;
  }

  void start(double frame_rate, int exposure_us) {
    camera_->requestCompleted.connect(this, &Session::on_request_completed);
    camera_->disconnected.connect(this, &Session::on_disconnected);
    connected_ = true;

    libcamera::ControlList controls(libcamera::controls::controls);
    if (frame_rate > 0) {
      if (camera_->controls().count(&libcamera::controls::FrameDurationLimits)) {
        const std::int64_t frame_us = std::llround(1e6 / frame_rate);
        const std::array<std::int64_t, 2> limits{frame_us, frame_us};
        // libcamera API: a Span is accepted by every version for array controls.
        controls.set(libcamera::controls::FrameDurationLimits, libcamera::Span<const std::int64_t, 2>(limits));
        frame_rate_ = frame_rate;
      } else {
        spdlog::warn("libcamera {}: no frame duration control; {} fps not applied", camera_->id(), frame_rate);
      }
    }
    if (exposure_us > 0) {
      if (camera_->controls().count(&libcamera::controls::ExposureTime) &&
          camera_->controls().count(&libcamera::controls::AeEnable)) {
        controls.set(libcamera::controls::AeEnable, false);
        controls.set(libcamera::controls::ExposureTime, exposure_us);
      } else {
        spdlog::warn("libcamera {}: no manual exposure control; exposure left automatic", camera_->id());
      }
    }
    if (const int error = camera_->start(&controls); error < 0) fail("cannot start: " + error_text(error));
    started_ = true;
    for (const auto& request : requests_)
      if (const int error = camera_->queueRequest(request.get()); error < 0)
        fail("cannot queue a request: " + error_text(error));
  }

  // libcamera's thread. Each notifies while it holds the lock: the capture thread, which may
  // destroy this session as soon as it sees gone_ (a timed wait that ends on its own), cannot
  // do so between the change and the notification.
  void on_request_completed(libcamera::Request* request) {
    std::lock_guard lock(mutex_);
    completed_.push_back(request);
    completed_cv_.notify_one();
  }
  void on_disconnected() {
    std::lock_guard lock(mutex_);
    gone_ = true;
    completed_cv_.notify_one();
  }

  std::shared_ptr<libcamera::Camera> camera_;
  bool acquired_ = false;
  bool connected_ = false;  // the slots are connected
  bool started_ = false;
  libcamera::Stream* stream_ = nullptr;
  unsigned width_ = 0, height_ = 0, stride_ = 0;
  double frame_rate_ = 0;
  std::optional<Chroma420> chroma_;  // where the stream's format keeps Cr; none in R8
  std::unique_ptr<libcamera::FrameBufferAllocator> allocator_;
  std::vector<Mapping> mappings_;
  std::vector<BufferPlanes> planes_;  // by request cookie
  cv::Mat gathered_cr_;               // Cr out of Cb Cr pairs (NV12, NV21), the latest frame's
  std::vector<std::unique_ptr<libcamera::Request>> requests_;

  mutable std::mutex mutex_;
  std::condition_variable completed_cv_;
  std::vector<libcamera::Request*> completed_;  // completed, not yet taken by grab()
  bool gone_ = false;                           // libcamera reported the camera unplugged
};

/// No camera by the configured id, or none at all: one may still appear (a CSI camera whose ISP
/// is enumerated after the daemon started at boot).
struct CameraAbsent : SourceError {
  using SourceError::SourceError;
};

}  // namespace

class LibcameraCamera::Impl {
 public:
  explicit Impl(LibcameraOptions options)
      : options_(std::move(options)),
        description_("libcamera:" + (options_.camera_id.empty() ? "(first camera)" : options_.camera_id)),
        frame_rate_(options_.frame_rate) {
    try {
      open();
    } catch (const CameraAbsent& absent) {
      if (!options_.wait_when_absent) throw;
      // As after a disconnect: grab() opens the camera when it appears.
      spdlog::warn("{}; waiting for it", absent.what());
      next_reconnect_ = Clock::now() + reconnect_backoff_.failed();
    }
  }

  GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) {
    const Clock::time_point deadline = Clock::now() + timeout;
    if (!session_ && !reconnect_before(deadline)) return GrabStatus::kDisconnected;
    if (held_ && !session_->requeue(std::exchange(held_, nullptr))) return disconnect();

    libcamera::Request* request = session_->wait_completed(deadline);
    if (!request) return session_->gone() ? disconnect() : GrabStatus::kTimeout;

    const libcamera::FrameMetadata& metadata = session_->metadata(*request);
    if (request->status() != libcamera::Request::RequestComplete ||
        metadata.status != libcamera::FrameMetadata::FrameSuccess) {
      return session_->requeue(request) ? GrabStatus::kCorrupt : disconnect();
    }
    held_ = request;
    // The buffer timestamp is the kernel's CLOCK_MONOTONIC capture time, in ns.
    const auto capture_ns = static_cast<std::int64_t>(metadata.timestamp);
    if (first_capture_ns_ < 0) first_capture_ns_ = capture_ns;
    frame.gray = session_->luma(*request);
    frame.cr = session_->cr(*request);
    frame.capture_time_ns = capture_ns;
    frame.sequence = sequence_for(metadata.sequence);
    frame.media_time_s = static_cast<double>(capture_ns - first_capture_ns_) * 1e-9;
    frame.source = description_;
    return GrabStatus::kFrame;
  }

  double frame_rate() const { return frame_rate_; }
  const std::string& describe() const { return description_; }

 private:
  /// Opens a session on the configured camera. The first camera found for an empty id becomes
  /// the id: a reconnect looks for that camera again.
  void open() {
    const auto cameras = lease_.manager().cameras();
    if (cameras.empty()) throw CameraAbsent("libcamera: no cameras found");
    if (options_.camera_id.empty()) {
      options_.camera_id = cameras.front()->id();
      description_ = "libcamera:" + options_.camera_id;
    }
    session_ = Session::open(find_camera(), options_);
    frame_rate_ = session_->frame_rate();
  }

  std::shared_ptr<libcamera::Camera> find_camera() {
    if (auto camera = lease_.manager().get(options_.camera_id)) return camera;
    std::string ids;
    for (const auto& camera : lease_.manager().cameras()) ids += (ids.empty() ? "" : ", ") + camera->id();
    throw CameraAbsent("libcamera: no camera \"" + options_.camera_id + "\" (cameras: " + (ids.empty() ? "none" : ids) +
                       ")");
  }

  GrabStatus disconnect() {
    spdlog::warn("{}: camera disconnected", description_);
    held_ = nullptr;
    session_.reset();
    stream_started_ = false;
    reconnect_backoff_.succeeded();  // the camera was up: retries start again at the first delay
    next_reconnect_ = Clock::now() + reconnect_backoff_.failed();
    return GrabStatus::kDisconnected;
  }

  /// Tries to reopen the camera once the back-off allows, waiting for that no later than
  /// `deadline`.
  bool reconnect_before(Clock::time_point deadline) {
    if (Clock::now() < next_reconnect_) {
      std::this_thread::sleep_until(std::min(deadline, next_reconnect_));
      if (Clock::now() < next_reconnect_) return false;
    }
    try {
      open();
    } catch (const SourceError& error) {
      spdlog::debug("{}: reconnect failed: {}", description_, error.what());
      next_reconnect_ = Clock::now() + reconnect_backoff_.failed();
      return false;
    }
    reconnect_backoff_.succeeded();
    spdlog::info("{}: camera connected", description_);
    return true;
  }

  /// Frame::sequence keeps counting across reconnects; libcamera restarts its own numbering
  /// with every start(), and its gaps are lost frames.
  std::uint64_t sequence_for(std::uint32_t camera_sequence) {
    if (!stream_started_) {
      stream_started_ = true;
      stream_base_ = next_sequence_;
      first_camera_sequence_ = camera_sequence;
    }
    const std::uint64_t sequence = stream_base_ + (camera_sequence - first_camera_sequence_);
    next_sequence_ = sequence + 1;
    return sequence;
  }

  // Declared first, destroyed last: the session releases its camera before the manager stops.
  ManagerLease lease_;
  LibcameraOptions options_;
  std::string description_;
  double frame_rate_;  // the requested rate until a session says what it applied
  std::unique_ptr<Session> session_;
  libcamera::Request* held_ = nullptr;  // the request whose buffer the caller's frame shows

  bool stream_started_ = false;
  std::uint64_t stream_base_ = 0;
  std::uint64_t next_sequence_ = 0;
  std::uint32_t first_camera_sequence_ = 0;
  std::int64_t first_capture_ns_ = -1;

  Backoff reconnect_backoff_{kReconnectInitial, kReconnectMax};
  Clock::time_point next_reconnect_{};
};

LibcameraCamera::LibcameraCamera(LibcameraOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}
LibcameraCamera::~LibcameraCamera() = default;

GrabStatus LibcameraCamera::grab(Frame& frame, std::chrono::milliseconds timeout) {
  return impl_->grab(frame, timeout);
}
double LibcameraCamera::frame_rate() const { return impl_->frame_rate(); }
std::string LibcameraCamera::describe() const { return impl_->describe(); }

}  // namespace lipdrive
