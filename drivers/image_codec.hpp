// Still images in and out through FFmpeg's codecs (libavcodec, libswscale): a camera's MJPEG
// frames to luma, the monitor's JPEG previews, the PNG files of `lipdrive plot` and
// `lipdrive model render`.
#pragma once

#include "drivers/video_file.hpp"

#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <string>

namespace lipdrive {

/// Decodes JPEG images one after another (a camera's MJPEG stream) to luma.
class JpegDecoder {
 public:
  JpegDecoder();
  ~JpegDecoder();
  JpegDecoder(const JpegDecoder&) = delete;
  JpegDecoder& operator=(const JpegDecoder&) = delete;

  /// The luma of one JPEG image into `gray` (its buffer kept while the size holds); false when
  /// the bytes are not a decodable JPEG image (`gray` is then left empty, never stale).
  bool decode(std::span<const std::uint8_t> jpeg, cv::Mat& gray);

 private:
  struct Codec;
  std::unique_ptr<Codec> codec_;
};

/// A JPEG file's bytes of an 8-bit gray or BGR image; `quality` 1..100 as libjpeg's scale
/// (FFmpeg's quantiser scale chosen to match it). Throws MediaError when FFmpeg cannot encode.
std::string encode_jpeg(const cv::Mat& image, int quality);

/// Writes an 8-bit gray or BGR image to a PNG file. Throws MediaError naming the file.
void write_png(const std::filesystem::path& file, const cv::Mat& image);

}  // namespace lipdrive
