// The frames of a video file or an image file (PNG, JPEG, BMP, PGM/PPM, TIFF), decoded by
// FFmpeg's libraries (libavformat, libavcodec, libswscale) to 8-bit luma: what the simulated
// camera replays and the offline commands read. An image is a video of one frame.
//
// Planes as a camera gives them: a Y'CbCr source gives its Y' plane expanded to full range
// (0..255) and its Cr plane as coded, an RGB source BT.601 luma and Cr; a gray source no Cr.
// The luma in square pixels: a file whose pixels are not square (anamorphic PAL, HDV) is
// stretched to the proportions it is shown in; the Cr plane stays as coded (its consumers map
// it by the ratio of the sizes).
// Turned as coded, not yet as shown: how the file means them to be seen (a phone held upright
// records its frames on their side and says so) is read beside them, DisplayOrientation.
#pragma once

#include "core/image_rotation.hpp"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

namespace lipdrive {

/// A file that cannot be opened or decoded; the message names the file.
struct MediaError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// The largest side of a picture a file may hold: the largest side a camera of the product is
/// configured with ([camera] width and height). A picture of 8192×8192 is 64 Mpx; a larger one
/// costs memory and time out of all proportion to its file (a 249 KB PNG of 16000×16000 took
/// 2.5 GB and 37 s), and is no camera's.
inline constexpr int kMaxPictureSide = 8192;

/// How a file means its frames to be seen: mirrored left to right first, then turned
/// clockwise by `turn`. From a video stream's display matrix
/// (its turn to the nearest quarter; a flip in the matrix is not applied) or a JPEG's EXIF
/// orientation (1-8, mirrored ones included; a PNG's or TIFF's is not read).
struct DisplayOrientation {
  Rotation turn = Rotation::k0;
  bool mirrored = false;
  bool operator==(const DisplayOrientation&) const = default;
};

class VideoFile {
 public:
  /// Opens the file's first video stream and its decoder. Throws MediaError naming the file,
  /// also where its pictures are larger than kMaxPictureSide on a side (found from the file's
  /// header where it states the size, else from FFmpeg's probe, held to kMaxPictureSide² pixels).
  explicit VideoFile(const std::filesystem::path& file);
  ~VideoFile();
  VideoFile(const VideoFile&) = delete;
  VideoFile& operator=(const VideoFile&) = delete;

  /// Frames per second the file declares (FFmpeg's guess); 0 when it declares none.
  double frame_rate() const { return frame_rate_; }
  /// Frames the file declares (or its duration implies); 0 when unknown. One pass's length, no
  /// measure of damage (damage() is): the duration may be the sound's, or FFmpeg's estimate.
  std::int64_t frame_count() const { return frame_count_; }
  /// The file's length in seconds as a player shows it: the longer of its picture and its sound
  /// (the container's duration, or FFmpeg's estimate); 0 when unknown.
  double length_s() const { return length_s_; }
  /// The slot of the frame read last: unique and increasing, where it lies on the file's timeline
  /// counted in periods of frame_rate() from the stream's start (its time times the frame rate,
  /// rounded), and at least the slot after the frame before; -1 before the first read. A
  /// recorder that dropped a frame leaves its slot empty (an AVI's empty chunk, a gap in an
  /// MP4's or Matroska's timestamps): the frames after it count from their own time, not from
  /// how many came before. Without timestamps or a frame rate, the frames read before it.
  /// A variable-rate file (a phone's, or parts at different rates joined) states one rate:
  /// frames closer together than its period take the next free slots and run ahead of their
  /// time (frame_time_s() is the time), until a gap or a slower stretch lets their time catch
  /// up; frames further apart leave slots empty, as dropped frames do.
  std::int64_t frame_index() const { return frame_index_; }
  /// When the frame read last is shown, in seconds from the stream's start (its timestamp, or
  /// FFmpeg's best guess at it, less the stream's start time); none when it has no timestamp.
  std::optional<double> frame_time_s() const { return frame_time_s_; }

  /// The next frame's luma into `gray` and its Cr into `cr` (empty without colour; buffers kept
  /// while the size holds). False at the end of the file, and where the rest of a damaged file
  /// cannot be decoded (damage()).
  bool read(cv::Mat& gray, cv::Mat& cr);
  /// Once read() has returned false: what shows the file damaged or truncated there, empty where
  /// it simply ended. Judged from what went wrong while reading (the demuxer or the decoder
  /// failed; the file ends inside a packet of its picture, or, where FFmpeg's parser hides the
  /// cut packet from us, the decoder patched up the last picture) or, where the file states exactly
  /// how many frames its picture shows (an AVI's or MP4's frame count, as an MP4's edit list
  /// shows them) or where it ends (a Matroska track's DURATION), frames ending short of it (the
  /// last frame's time and the gap before it more than a period short of that end). Not from
  /// the file's length, which its sound may outlast, nor from durations FFmpeg estimates (an
  /// MPEG program or transport stream states none: one cut between its pictures ends as a
  /// shorter one does). In an MPEG program or transport stream, also from frames missing in
  /// the middle: a jump in its timestamps past how long the frame before is shown.
  const std::string& damage() const;
  /// Once damage() says something: how many of the picture's frames were lost, where that can
  /// be known (frames short of those the file states or of where it says it ends, frames missing
  /// where an MPEG stream's timestamps jump, packets the decoder refused); none where the file
  /// ends early and does not say how long it is (an MPEG program stream or FLV file cut short).
  std::optional<std::int64_t> lost_frames() const { return lost_frames_; }
  /// How the frame read last is meant to be seen.
  DisplayOrientation orientation() const { return orientation_; }

 private:
  struct Decoder;
  // At the end of the pictures: damage() from the frames short of the file's stated end or
  // missing in its gaps, and lost_frames().
  void judge_end();

  std::unique_ptr<Decoder> decoder_;
  double frame_rate_ = 0;
  std::int64_t frame_count_ = 0;
  double length_s_ = 0;
  std::int64_t stated_frames_ = 0;      // the picture's frames as the file states them exactly; 0: none
  std::optional<double> stated_end_s_;  // where a Matroska track says its picture ends
  std::int64_t frame_index_ = -1;
  std::optional<double> frame_time_s_, previous_time_s_;  // the frame read last, and the one before
  // An MPEG program or transport stream codes a frame for every period of its rate (a frame a
  // camera missed is a picture repeated, not left out): a jump in its timestamps is frames lost
  // in the file, not a recorder's empty slot.
  bool gaps_are_losses_ = false;
  double shown_for_s_ = 0;             // how long the frame read last is shown (a period where it says not)
  std::int64_t lost_in_gaps_ = 0;      // frames missing where the timestamps jump
  std::optional<double> first_gap_s_;  // the time of the frame before the first such jump
  std::optional<std::int64_t> lost_frames_;
  DisplayOrientation stream_orientation_, orientation_;
};

/// The luma and Cr of the first frame of an image (or video) file, and how it is meant to be
/// seen. Throws MediaError naming the file when it cannot be opened or holds no decodable frame.
DisplayOrientation read_image(const std::filesystem::path& file, cv::Mat& gray, cv::Mat& cr);

}  // namespace lipdrive
