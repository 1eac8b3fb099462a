#include "sim/simulated_camera.hpp"

#include "core/image_rotation.hpp"
#include "drivers/clock.hpp"

#include <opencv2/core.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <ctime>
#include <system_error>
#include <utility>

namespace lipdrive {
namespace {

// Sleeping to an absolute deadline (not for a duration) keeps the replay from drifting.
void sleep_until_ns(std::int64_t deadline_ns) {
  const timespec deadline{static_cast<time_t>(deadline_ns / 1'000'000'000),
                          static_cast<long>(deadline_ns % 1'000'000'000)};
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &deadline, nullptr) == EINTR) {
  }
}

std::string lower_case(std::string text) {
  std::ranges::transform(text, text.begin(), [](unsigned char c) { return std::tolower(c); });
  return text;
}

std::vector<std::filesystem::path> list_images(const std::filesystem::path& folder) {
  std::vector<std::filesystem::path> images;
  try {
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
      if (entry.is_regular_file() && is_image_file_name(entry.path())) images.push_back(entry.path());
    }
  } catch (const std::filesystem::filesystem_error& e) {
    throw SourceError(folder.string() + ": cannot read the folder: " + e.code().message());
  }
  if (images.empty())
    throw SourceError(folder.string() + ": no images (png, jpg, jpeg, bmp, pgm, ppm, tif) in the folder");
  std::ranges::sort(images, {}, [](const auto& path) { return path.filename().string(); });
  return images;
}

}  // namespace

bool is_image_file_name(const std::filesystem::path& path) {
  static constexpr std::array<std::string_view, 8> kExtensions{".png", ".jpg", ".jpeg", ".bmp",
                                                               ".pgm", ".ppm", ".tif",  ".tiff"};
  return std::ranges::find(kExtensions, lower_case(path.extension().string())) != kExtensions.end();
}

SimulatedCamera::SimulatedCamera(SimulatedCameraOptions options, ReplayClock* clock)
    : options_(std::move(options)), clock_(clock) {
  const auto& input = options_.input;
  std::error_code ec;
  if (!std::filesystem::exists(input, ec)) throw SourceError(input.string() + ": no such file or folder");
  if (!(options_.image_frame_rate > 0)) throw SourceError(input.string() + ": the image frame rate must be positive");

  if (std::filesystem::is_directory(input, ec)) {
    kind_ = Kind::kImages;
    images_ = list_images(input);
  } else if (is_image_file_name(input)) {
    kind_ = Kind::kImages;
    images_ = {input};
    try {
      Frame shown;
      show(read_image(input, gray_, cr_), shown);
      single_image_ = shown.gray.clone();
      single_image_cr_ = shown.cr.clone();
    } catch (const MediaError& e) {
      throw SourceError(e.what());
    }
  } else {
    kind_ = Kind::kVideo;
    video_path_ = input.string();
    open_video();
  }
  for (const auto& image : images_) image_names_.push_back(image.filename().string());

  if (kind_ == Kind::kImages) frame_rate_ = options_.image_frame_rate;
  if (options_.replay_rate > 0) frame_rate_ = options_.replay_rate;
  if (clock_) clock_->set_loop_s(options_.loop ? duration_s() : 0);
}

void SimulatedCamera::open_video() {
  try {
    video_.reset();  // one decoder at a time
    video_ = std::make_unique<VideoFile>(video_path_);
  } catch (const MediaError& e) {
    throw SourceError(e.what());
  }
  const double fps = video_->frame_rate();
  frame_rate_ = options_.replay_rate > 0 ? options_.replay_rate : fps > 0 ? fps : options_.image_frame_rate;
}

std::string SimulatedCamera::describe() const { return "sim:" + options_.input.string(); }

double SimulatedCamera::duration_s() const {
  // In whole periods of its rate, so that each pass begins in a slot of its own (and FFmpeg's
  // estimate of an MPEG stream's length, which may end at its last frame's start, is covered).
  if (follows_frame_times() && video_->length_s() > 0)
    return std::ceil(video_->length_s() * frame_rate_ - 1e-6) / frame_rate_;
  const auto frames = kind_ == Kind::kVideo ? video_->frame_count() : static_cast<std::int64_t>(images_.size());
  return static_cast<double>(frames) / frame_rate_;
}

void SimulatedCamera::rewind() {
  position_ = 0;
  last_index_ = -1;
  // The next pass begins a pass's length after this one (where the sound loops), and never
  // before the slot after the last frame delivered (a file whose length falls short of it); a
  // pass cut short by damage, in that slot (the length the file states is not there to wait
  // for; the clip's sound, which loops at that length, then runs out of step with the picture).
  if (follows_frame_times()) {
    const double next_slot_s = static_cast<double>(sequence_) / frame_rate_;
    pass_start_s_ = damaged_pass_ ? next_slot_s : std::max(pass_start_s_ + duration_s(), next_slot_s);
    sequence_ =
        std::max<std::uint64_t>(sequence_, static_cast<std::uint64_t>(std::llround(pass_start_s_ * frame_rate_)));
  }
  damaged_pass_ = false;
  // Reopening is exact where seeking to frame 0 is not for every codec.
  if (kind_ == Kind::kVideo) open_video();
}

std::int64_t SimulatedCamera::period_ns_of_rate() const { return std::llround(1e9 / frame_rate_); }

bool SimulatedCamera::follows_frame_times() const { return kind_ == Kind::kVideo && options_.replay_rate <= 0; }

bool SimulatedCamera::wait_until_due(std::chrono::milliseconds timeout, std::int64_t shift_ns) const {
  const std::int64_t period_ns = period_ns_of_rate();
  const std::int64_t deadline = start_ns_ + static_cast<std::int64_t>(sequence_) * period_ns + shift_ns;
  const std::int64_t now = monotonic_ns();
  const std::int64_t timeout_ns = std::chrono::nanoseconds(timeout).count();
  if (deadline - now > timeout_ns) {
    sleep_until_ns(now + timeout_ns);
    return false;
  }
  sleep_until_ns(deadline);
  return true;
}

std::optional<GrabStatus> SimulatedCamera::injected_outage(std::chrono::milliseconds timeout) {
  if (outage_until_ns_ == 0) return std::nullopt;
  const std::int64_t timeout_end = monotonic_ns() + std::chrono::nanoseconds(timeout).count();
  if (outage_until_ns_ > timeout_end) {
    sleep_until_ns(timeout_end);
    return outage_status_;
  }
  sleep_until_ns(outage_until_ns_);
  outage_until_ns_ = 0;
  if (clock_ && start_ns_ != 0) {
    skip_frames_due();
    return std::nullopt;
  }
  // Resume at the recording's pace from now on, not with a burst of overdue frames.
  const std::int64_t period_ns = period_ns_of_rate();
  start_ns_ = monotonic_ns() - static_cast<std::int64_t>(sequence_) * period_ns;
  return std::nullopt;
}

void SimulatedCamera::skip_frames_due() {
  const std::int64_t period_ns = period_ns_of_rate();
  const auto due = static_cast<std::uint64_t>(std::max<std::int64_t>(monotonic_ns() - start_ns_, 0) / period_ns);
  while (sequence_ < due) {
    if (!read_next()) return;  // grab() finds the end itself
    held_ = false;
    ++sequence_;  // never delivered: the gap in the sequence numbers shows the loss
  }
}

bool SimulatedCamera::read_next() {
  if (held_) return true;
  GrabStatus status = read_frame(next_);
  // position_ > 0: a recording without a single frame must not loop forever.
  if (status == GrabStatus::kEndOfStream && options_.loop && position_ > 0) {
    rewind();
    status = read_frame(next_);
  }
  if (status == GrabStatus::kEndOfStream) return false;
  next_status_ = status;
  held_ = true;
  return true;
}

GrabStatus SimulatedCamera::inject_frame_faults() {
  const SimulatedCameraOptions::FaultInjection& faults = options_.faults;
  const std::int64_t n = ++frames_read_;
  const auto every = [n](int period) { return period > 0 && n % period == 0; };
  const auto begin_outage = [this](GrabStatus status, std::chrono::milliseconds duration) {
    outage_status_ = status;
    outage_until_ns_ = monotonic_ns() + std::chrono::nanoseconds(duration).count();
  };
  if (n == faults.disconnect_after)
    begin_outage(GrabStatus::kDisconnected, faults.reconnect);
  else if (every(faults.stall_every))
    begin_outage(GrabStatus::kTimeout, faults.stall);
  // A dropped frame is never seen; the gap in the sequence numbers shows it.
  if (every(faults.drop_every)) return GrabStatus::kTimeout;
  if (every(faults.corrupt_every)) {
    return corrupt(describe() + ": injected fault: frame " + std::to_string(n) + " is corrupt", 1);
  }
  return GrabStatus::kFrame;
}

GrabStatus SimulatedCamera::grab(Frame& frame, std::chrono::milliseconds timeout) {
  if (ended_ && !held_) return GrabStatus::kEndOfStream;
  if (const auto outage = injected_outage(timeout)) return *outage;
  if (options_.real_time) {
    if (start_ns_ == 0) start_ns_ = clock_ ? clock_->start_ns() : monotonic_ns();
    // Frames a period apart are read when the next one is due (decoding then, as a camera
    // delivers, not while the frame before is processed). A video's frames at their own times
    // are read at once: when the next is due is known only from the frame itself (a faster
    // stretch's first frame is due less than a period after the one before), and it is held
    // until then.
    if (!follows_frame_times() && !wait_until_due(timeout, 0)) return GrabStatus::kTimeout;
  }
  // A frame after slots the recorder left empty is held to its own.
  if (!read_next()) {
    ended_ = true;
    return GrabStatus::kEndOfStream;
  }
  if (options_.real_time && !wait_until_due(timeout, held_shift_ns_)) return GrabStatus::kTimeout;
  held_ = false;
  frame = next_;
  // A frame that could not be decoded still used up its slot: the sequence gap shows it.
  frame.sequence = sequence_++;
  frame.capture_time_ns = monotonic_ns();
  return next_status_ == GrabStatus::kFrame ? inject_frame_faults() : next_status_;
}

GrabStatus SimulatedCamera::corrupt(std::string error, std::optional<std::int64_t> lost) {
  last_error_ = std::move(error);
  lost_frames_ = lost;
  return GrabStatus::kCorrupt;
}

GrabStatus SimulatedCamera::read_frame(Frame& frame) {
  return kind_ == Kind::kVideo ? read_video_frame(frame) : read_image_frame(frame);
}

GrabStatus SimulatedCamera::read_video_frame(Frame& frame) {
  if (!video_->read(gray_, cr_)) {
    if (video_->damage().empty() || damaged_pass_) return GrabStatus::kEndOfStream;
    const GrabStatus status =
        corrupt(video_path_ + ": decoding stopped at frame " + std::to_string(video_->frame_index() + 1) + ": " +
                    video_->damage() + " (the file is damaged or truncated)",
                video_->lost_frames());
    // Nothing after the damage is readable: the replay ends here, or a looping one (the daemon's)
    // starts over at its first frame, said once in the log.
    if (options_.loop) {
      damaged_pass_ = true;
      if (!std::exchange(damage_logged_, true))
        spdlog::warn("{}; the replay loops over the frames before it", *last_error_);
    } else {
      ended_ = true;
    }
    return status;
  }
  show(video_->orientation(), frame);
  // Slots the recorder left empty before this frame are slots of the replay too.
  const std::int64_t index = video_->frame_index();
  sequence_ += static_cast<std::uint64_t>(std::max<std::int64_t>(index - last_index_ - 1, 0));
  last_index_ = index;
  // Its own time on the recording's timeline: a variable-rate clip's frames are not a period
  // apart, and its sound is heard at their times. At a replay rate of its own the replay's
  // slots are the timeline.
  const double slot_time_s = static_cast<double>(index) / frame_rate_;
  frame.media_time_s = follows_frame_times() ? video_->frame_time_s().value_or(slot_time_s) : slot_time_s;
  // Due at its time in this pass, however far that lies from the slot it is delivered in.
  held_shift_ns_ = follows_frame_times() ? std::llround((pass_start_s_ + frame.media_time_s) * 1e9) -
                                               static_cast<std::int64_t>(sequence_) * period_ns_of_rate()
                                         : 0;
  frame.source = video_path_;
  ++position_;
  return GrabStatus::kFrame;
}

GrabStatus SimulatedCamera::read_image_frame(Frame& frame) {
  if (position_ >= static_cast<std::int64_t>(images_.size())) return GrabStatus::kEndOfStream;
  const auto index = static_cast<std::size_t>(position_++);
  frame.media_time_s = static_cast<double>(index) / frame_rate_;
  frame.source = image_names_[index];
  if (!single_image_.empty()) {
    frame.gray = single_image_;
    frame.cr = single_image_cr_;
    return GrabStatus::kFrame;
  }
  try {
    show(read_image(images_[index], gray_, cr_), frame);
  } catch (const MediaError& e) {
    return corrupt(e.what(), 1);
  }
  return GrabStatus::kFrame;
}

void SimulatedCamera::show(DisplayOrientation orientation, Frame& frame) {
  if (orientation.mirrored) {
    cv::flip(gray_, gray_, 1);
    if (!cr_.empty()) cv::flip(cr_, cr_, 1);
  }
  const bool turned = orientation.turn != Rotation::k0;
  if (turned) {
    rotate_plane(gray_, turned_gray_, orientation.turn);
    rotate_plane(cr_, turned_cr_, orientation.turn);
  }
  frame.gray = turned ? turned_gray_ : gray_;
  frame.cr = turned ? turned_cr_ : cr_;
}

}  // namespace lipdrive
