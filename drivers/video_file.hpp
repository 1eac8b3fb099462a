// The frames of a video file or an image file (PNG, JPEG, BMP, PGM/PPM, TIFF), decoded by
// FFmpeg's libraries (libavformat, libavcodec, libswscale) to 8-bit luma: what the simulated
// camera replays and the offline commands read. An image is a video of one frame.
//
// Planes as a camera gives them: a Y'CbCr source gives its Y' plane expanded to full range
// (0..255) and its Cr plane as coded, an RGB source BT.601 luma and Cr; a gray source no Cr.
#pragma once

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

namespace lipdrive {

/// A file that cannot be opened or decoded; the message names the file.
struct MediaError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class VideoFile {
 public:
  /// Opens the file's first video stream and its decoder. Throws MediaError naming the file.
  explicit VideoFile(const std::filesystem::path& file);
  ~VideoFile();
  VideoFile(const VideoFile&) = delete;
  VideoFile& operator=(const VideoFile&) = delete;

  /// Frames per second the file declares (FFmpeg's guess); 0 when it declares none.
  double frame_rate() const { return frame_rate_; }
  /// Frames the file declares (or its duration implies); 0 when unknown.
  std::int64_t frame_count() const { return frame_count_; }

  /// The next frame's luma into `gray` and its Cr into `cr` (empty without colour; buffers kept
  /// while the size holds). False at the end of the file, and where the rest of a damaged file
  /// cannot be decoded.
  bool read(cv::Mat& gray, cv::Mat& cr);

 private:
  struct Decoder;
  std::unique_ptr<Decoder> decoder_;
  double frame_rate_ = 0;
  std::int64_t frame_count_ = 0;
};

/// The luma and Cr of the first frame of an image (or video) file. Throws MediaError naming
/// the file when it cannot be opened or holds no decodable frame.
void read_image(const std::filesystem::path& file, cv::Mat& gray, cv::Mat& cr);

}  // namespace lipdrive
