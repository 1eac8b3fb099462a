// What the FFmpeg wrappers share (audio_file, video_file, image_codec): owning handles for
// FFmpeg's C objects, its error text, and a decoded picture's luma.
#pragma once

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/error.h>
#include <libswscale/swscale.h>
}

#include <opencv2/core/mat.hpp>

#include <array>
#include <memory>
#include <string>

namespace lipdrive::ffmpeg {

inline std::string error_text(int error) {
  std::array<char, AV_ERROR_MAX_STRING_SIZE> text{};
  av_strerror(error, text.data(), text.size());
  return text.data();
}

struct FormatCloser {
  void operator()(AVFormatContext* c) const { avformat_close_input(&c); }
};
struct CodecFreer {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
};
struct PacketFreer {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};
struct FrameFreer {
  void operator()(AVFrame* f) const { av_frame_free(&f); }
};

using Format = std::unique_ptr<AVFormatContext, FormatCloser>;
using Codec = std::unique_ptr<AVCodecContext, CodecFreer>;
using Packet = std::unique_ptr<AVPacket, PacketFreer>;
using Frame = std::unique_ptr<AVFrame, FrameFreer>;

/// A decoded picture's luma as 8-bit full range: Y' expanded from video range where the
/// picture is in it, BT.601 luma of an RGB picture. Keeps its scaler while the format holds.
class LumaConverter {
 public:
  LumaConverter() = default;
  ~LumaConverter() { sws_freeContext(scaler_); }
  LumaConverter(const LumaConverter&) = delete;
  LumaConverter& operator=(const LumaConverter&) = delete;

  /// False when libswscale cannot convert the picture's format.
  bool convert(const AVFrame& picture, cv::Mat& gray) {
    const auto format = static_cast<AVPixelFormat>(picture.format);
    const AVPixelFormat layout = without_range(format);
    scaler_ = sws_getCachedContext(scaler_, picture.width, picture.height, layout, picture.width, picture.height,
                                   AV_PIX_FMT_GRAY8, SWS_POINT, nullptr, nullptr, nullptr);
    if (scaler_ == nullptr) return false;
    const bool full_range = picture.color_range == AVCOL_RANGE_JPEG || layout != format;
    const int* coefficients = sws_getCoefficients(SWS_CS_ITU601);
    sws_setColorspaceDetails(scaler_, coefficients, full_range ? 1 : 0, coefficients, 1, 0, 1 << 16, 1 << 16);
    gray.create(picture.height, picture.width, CV_8UC1);
    std::uint8_t* planes[] = {gray.data};
    const int strides[] = {static_cast<int>(gray.step[0])};
    return sws_scale(scaler_, picture.data, picture.linesize, 0, picture.height, planes, strides) == picture.height;
  }

  /// JPEG's full-range formats as the same layout in video range (libswscale takes the range
  /// apart, and warns about the old formats that carry it).
  static AVPixelFormat without_range(AVPixelFormat format) {
    switch (format) {
      case AV_PIX_FMT_YUVJ420P: return AV_PIX_FMT_YUV420P;
      case AV_PIX_FMT_YUVJ422P: return AV_PIX_FMT_YUV422P;
      case AV_PIX_FMT_YUVJ444P: return AV_PIX_FMT_YUV444P;
      case AV_PIX_FMT_YUVJ440P: return AV_PIX_FMT_YUV440P;
      case AV_PIX_FMT_YUVJ411P: return AV_PIX_FMT_YUV411P;
      default: return format;
    }
  }

 private:
  SwsContext* scaler_ = nullptr;
};

}  // namespace lipdrive::ffmpeg
