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

/// Decodes JPEG images one after another (a camera's MJPEG stream) to luma and Cr.
class JpegDecoder {
 public:
  JpegDecoder();
  ~JpegDecoder();
  JpegDecoder(const JpegDecoder&) = delete;
  JpegDecoder& operator=(const JpegDecoder&) = delete;

  /// The luma of one JPEG image into `gray` and its Cr into `cr` (buffers kept while the size
  /// holds; `cr` empty for a gray JPEG); false when the bytes are not a decodable JPEG image
  /// (both are then left empty, never stale).
  bool decode(std::span<const std::uint8_t> jpeg, cv::Mat& gray, cv::Mat& cr);

 private:
  struct Codec;
  std::unique_ptr<Codec> codec_;
};

/// Encodes 8-bit gray or BGR images to JPEG one after another (the monitor's previews): the
/// scaler, the picture and FFmpeg's encoder are made for the first image and kept while its
/// size and kind hold.
class JpegEncoder {
 public:
  /// `quality` 1..100 as libjpeg's scale (FFmpeg's quantiser scale chosen to match it).
  explicit JpegEncoder(int quality);
  ~JpegEncoder();
  JpegEncoder(const JpegEncoder&) = delete;
  JpegEncoder& operator=(const JpegEncoder&) = delete;

  /// A JPEG file's bytes of `image`. Throws MediaError when FFmpeg cannot encode it.
  std::string encode(const cv::Mat& image);

 private:
  struct Codec;
  std::unique_ptr<Codec> codec_;
};

/// Writes an 8-bit gray or BGR image to a PNG file. Throws MediaError naming the file.
void write_png(const std::filesystem::path& file, const cv::Mat& image);

}  // namespace lipdrive
