// A FrameSource that replays a recording: a video file, a single image, or a folder of
// images in file-name order, decoded by FFmpeg's libraries (drivers/video_file.hpp). CI and a bench without
// hardware run the whole pipeline through it (docs/data-flow.md).
#pragma once

#include "drivers/frame_source.hpp"
#include "drivers/video_file.hpp"
#include "sim/replay_clock.hpp"

#include <opencv2/core/mat.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace lipdrive {

struct SimulatedCameraOptions {
  /// Faults the replay injects into an otherwise clean recording, so the pipeline's
  /// handling of a misbehaving camera can be tested without one. 0 disables each fault.
  /// Counts are of frames the camera would have delivered.
  struct FaultInjection {
    int drop_every = 0;   // every Nth frame is skipped (a sequence gap, as a real camera shows)
    int stall_every = 0;  // the frame after every Nth arrives `stall` late
    std::chrono::milliseconds stall{0};
    int disconnect_after = 0;                // after N frames the camera reports kDisconnected for `reconnect`,
    std::chrono::milliseconds reconnect{0};  // then delivers again (once per replay)
    int corrupt_every = 0;                   // every Nth frame is kCorrupt
  };

  std::filesystem::path input;   // video file, image file, or folder of images
  bool real_time = false;        // pace at the recording's own times; else as fast as possible
  bool loop = false;             // restart at the end instead of reporting kEndOfStream
  double image_frame_rate = 25;  // frames per second for images and folders (and videos without one)
  double replay_rate = 0;        // > 0: replay at this many frames per second instead (a 60 fps bench
                                 // from a 25 fps recording), whatever the frames' own times; media
                                 // time follows the replay rate
  FaultInjection faults{};
};

/// Image file extensions a folder replay picks up (lower case, with the dot).
bool is_image_file_name(const std::filesystem::path& path);

class SimulatedCamera : public FrameSource {
 public:
  /// Opens the input. Throws SourceError naming the path when it is missing, an empty
  /// or unreadable folder, or a file that is neither a decodable image nor a video.
  /// `clock` (not owned; it outlives the camera): the real-time replay keeps to this timeline,
  /// shared with the clip's simulated sound (sim/simulated_audio.hpp): a video's frame is due at
  /// its start + its own time on the recording (media_time_s; at a replay rate, and an image, n
  /// periods for frame n), and after an injected outage the replay goes on with the frame due
  /// then, as a camera that comes back shows the present. Without it the replay starts at the
  /// first grab() and resumes after an outage where it stopped. A looping replay sets the
  /// clock's loop length to duration_s().
  explicit SimulatedCamera(SimulatedCameraOptions options, ReplayClock* clock = nullptr);

  /// Delivers the next frame. A video whose reading ends in damage (VideoFile::damage(): a
  /// file cut short, not one whose sound outlasts its picture) yields kCorrupt once (details
  /// in last_error()), then ends (looping: starts over, a kCorrupt in every pass); an undecodable image inside a folder yields kCorrupt for
  /// that frame only. In real time, kTimeout when the next frame is due later than `timeout`.
  GrabStatus grab(Frame& frame, std::chrono::milliseconds timeout) override;
  double frame_rate() const override { return frame_rate_; }
  std::string describe() const override;
  /// One pass through the recording, in seconds: a looping replay restarts this often, and the
  /// clip's simulated sound loops at it too, so the two stay in step pass after pass. A video at
  /// its own rate: the file's length as a player shows it, the longer of its picture and its
  /// sound (a sound that outlasts the picture is heard to its end, the picture holding its last
  /// frame: no frames come in its tail, the slots there left empty), in whole periods of its
  /// rate; where the file states no length, its frames at its rate. At a replay rate, and
  /// images: the frames at that rate. 0 when a video says neither.
  double duration_s() const;

  /// Images (a folder or a single one): every frame is unrelated to the last, so a tracker
  /// detects the face afresh in each; a video's frames follow one another.
  bool independent_frames() const { return kind_ == Kind::kImages; }

  /// What went wrong with the most recent kCorrupt, if anything did.
  const std::optional<std::string>& last_error() const { return last_error_; }
  /// How many of the recording's frames the most recent kCorrupt stands for: 1 for a picture (or
  /// an injected fault), a damaged video's VideoFile::lost_frames(), none where that file ends
  /// early without saying how long it is.
  std::optional<std::int64_t> lost_frames() const { return lost_frames_; }

 private:
  enum class Kind { kVideo, kImages };

  void open_video();
  void rewind();
  GrabStatus read_frame(Frame& frame);  // kEndOfStream past the last frame
  // kCorrupt, saying what went wrong and how many frames it stands for (lost_frames()).
  GrabStatus corrupt(std::string error, std::optional<std::int64_t> lost);
  GrabStatus read_video_frame(Frame& frame);
  GrabStatus read_image_frame(Frame& frame);
  // gray_ and cr_ as their file means them to be seen: mirrored in place, turned into
  // turned_gray_ / turned_cr_; `frame` points at the planes that hold them.
  void show(DisplayOrientation orientation, Frame& frame);
  // Real-time pacing: false (after sleeping `timeout`) when the frame is not due yet. Slot n is
  // due at start + n periods, a frame `shift_ns` from its slot's time that much later.
  bool wait_until_due(std::chrono::milliseconds timeout, std::int64_t shift_ns) const;
  // A video replayed at its own rate: each frame is due at its own time, not a period after the
  // one before.
  bool follows_frame_times() const;
  // One frame period at frame_rate_ (the replay's slots), in nanoseconds.
  std::int64_t period_ns_of_rate() const;
  // Fault injection: the status while an injected disconnect or stall lasts, else nullopt.
  std::optional<GrabStatus> injected_outage(std::chrono::milliseconds timeout);
  // Fault injection on a frame just read: kFrame, or what the fault makes of it.
  GrabStatus inject_frame_faults();
  // With a shared clock, after an outage: reads past the frames that fell due meanwhile.
  void skip_frames_due();
  // Reads the next frame into next_ unless one is held there (looping at the end); false at
  // the end of a recording that does not loop.
  bool read_next();

  SimulatedCameraOptions options_;
  ReplayClock* clock_;
  Kind kind_;
  std::string video_path_;  // `source` of video frames
  std::vector<std::filesystem::path> images_;
  std::vector<std::string> image_names_;    // `source` of image frames (file names)
  cv::Mat single_image_, single_image_cr_;  // a lone image is decoded once, up front

  std::unique_ptr<VideoFile> video_;  // the open video (reopened to rewind)
  double frame_rate_ = 0;
  cv::Mat gray_, cr_;                 // decoded luma and Cr planes, reused across frames
  cv::Mat turned_gray_, turned_cr_;   // the same turned as the file means them to be seen

  std::int64_t position_ = 0;     // index of the next frame within the recording
  std::int64_t last_index_ = -1;  // the last video frame's place on the file's timeline
  std::uint64_t sequence_ = 0;    // next sequence number (slot), never reset by looping
  Frame next_;                    // a frame read but not delivered yet: held to its slot
  GrabStatus next_status_ = GrabStatus::kFrame;
  bool held_ = false;
  bool ended_ = false;
  bool damaged_pass_ = false;         // a looping replay met the file's damage in this pass
  bool damage_logged_ = false;        // and said so
  std::int64_t start_ns_ = 0;         // real-time pacing: deadline of frame n = start + n * period
  // Real-time pacing at a video's own rate: the frame read last is due at its own time, this far
  // from its slot's (a variable-rate clip's frames are not a period apart).
  std::int64_t held_shift_ns_ = 0;
  double pass_start_s_ = 0;           // a video at its own rate: where this pass begins on the replay's timeline
  std::int64_t frames_read_ = 0;      // fault injection: frames read from the recording
  std::int64_t outage_until_ns_ = 0;  // fault injection: end of a disconnect or stall, 0 = none
  GrabStatus outage_status_ = GrabStatus::kTimeout;
  std::optional<std::string> last_error_;
  std::optional<std::int64_t> lost_frames_;
};

}  // namespace lipdrive
