// What the FFmpeg wrappers share (audio_file, video_file, image_codec): owning handles for
// FFmpeg's C objects, its error text, and a decoded picture's luma and red-difference chroma.
#pragma once

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/error.h>
#include <libavutil/pixdesc.h>
#include <libswscale/swscale.h>
}

#include <opencv2/core/mat.hpp>

#include <algorithm>
#include <array>
#include <cmath>
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

/// A decoded picture's planes for the tracker: its luma as 8-bit full range (Y' expanded from
/// video range where the picture is in it, BT.601 luma of an RGB picture) and its Cr. Keeps its
/// scalers while the format holds.
class PictureConverter {
 public:
  PictureConverter() = default;
  ~PictureConverter() {
    sws_freeContext(scaler_);
    sws_freeContext(chroma_scaler_);
  }
  PictureConverter(const PictureConverter&) = delete;
  PictureConverter& operator=(const PictureConverter&) = delete;

  /// The picture's luma in square pixels: a picture whose pixels are not square (`sample_aspect`,
  /// their width over their height, as FFmpeg guesses it: anamorphic PAL or HDV, 0/1 when
  /// unknown) is stretched, never shrunk, to the proportions it is shown in, so that a face keeps
  /// the shape the detector and the landmark predictor know. An interlaced picture is read from
  /// its first field alone (first_field()), brought back to the picture's height. False when
  /// libswscale cannot convert the picture's format.
  bool convert(const AVFrame& picture, cv::Mat& gray, AVRational sample_aspect) {
    const auto format = static_cast<AVPixelFormat>(picture.format);
    const AVPixelFormat layout = without_range(format);
    const Lines lines = first_field(picture);
    const cv::Size shown = shown_size(picture.width, picture.height, sample_aspect);
    const bool resized = shown != cv::Size(picture.width, lines.height);
    scaler_ = sws_getCachedContext(scaler_, picture.width, lines.height, layout, shown.width, shown.height,
                                   AV_PIX_FMT_GRAY8, resized ? SWS_BILINEAR : SWS_POINT, nullptr, nullptr, nullptr);
    if (scaler_ == nullptr) return false;
    const bool full_range = picture.color_range == AVCOL_RANGE_JPEG || layout != format;
    const int* coefficients = sws_getCoefficients(SWS_CS_ITU601);
    sws_setColorspaceDetails(scaler_, coefficients, full_range ? 1 : 0, coefficients, 1, 0, 1 << 16, 1 << 16);
    padded_plane(gray, shown.height, shown.width);
    std::uint8_t* planes[] = {gray.data};
    const int strides[] = {static_cast<int>(gray.step[0])};
    return sws_scale(scaler_, lines.data, lines.linesize, 0, lines.height, planes, strides) == shown.height;
  }

  /// The rows of a picture's planes that the tracker reads.
  struct Lines {
    const std::uint8_t* data[AV_NUM_DATA_POINTERS] = {};
    int linesize[AV_NUM_DATA_POINTERS] = {};
    int height = 0;      // of the luma plane
    bool field = false;  // every second line of an interlaced picture
  };

  /// An interlaced picture holds two fields in alternate lines, captured half a frame period
  /// apart: a mouth that moves between them shows both positions combed together, which the
  /// landmark predictor reads as neither. Its first field in time (the one the picture's
  /// timestamp is for: the top one of a top-field-first picture) is every second line of
  /// each plane, its height rounded down so that the chroma lines stay inside the field. A
  /// progressive picture is taken whole.
  static Lines first_field(const AVFrame& picture) {
    Lines lines;
    const auto format = static_cast<AVPixelFormat>(picture.format);
    const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(format);
    const bool interlaced = picture.interlaced_frame != 0 && desc != nullptr && picture.height >= 4 &&
                            (desc->flags & AV_PIX_FMT_FLAG_PAL) == 0;
    const int field = interlaced && picture.top_field_first == 0 ? 1 : 0;
    const int planes = interlaced ? av_pix_fmt_count_planes(format) : 0;
    for (int p = 0; p < AV_NUM_DATA_POINTERS; ++p) {
      const bool split = p < planes && picture.data[p] != nullptr;
      lines.data[p] =
          split ? picture.data[p] + static_cast<std::ptrdiff_t>(field) * picture.linesize[p] : picture.data[p];
      lines.linesize[p] = split ? 2 * picture.linesize[p] : picture.linesize[p];
    }
    lines.field = interlaced;
    lines.height = interlaced ? (picture.height / 2) >> desc->log2_chroma_h << desc->log2_chroma_h : picture.height;
    return lines;
  }

  /// A width × height picture of pixels `sample_aspect` wide for each unit of height, in square
  /// pixels: the shorter side stretched. A ratio within 1 % of 1, or unknown, keeps the size, and
  /// so does one no camera uses (outside 1:2 to 2:1; anamorphic video's are 0.9 to 1.8): a
  /// file's pHYs of 2000:1 would ask for a picture thousands of times its size.
  static cv::Size shown_size(int width, int height, AVRational sample_aspect) {
    const double ratio = sample_aspect.num > 0 && sample_aspect.den > 0 ? av_q2d(sample_aspect) : 1.0;
    if (std::abs(ratio - 1.0) < 0.01 || ratio < 0.5 || ratio > 2.0) return {width, height};
    if (ratio > 1) return {static_cast<int>(std::lround(width * ratio)), height};
    return {width, static_cast<int>(std::lround(height / ratio))};
  }

  /// The picture's red-difference chroma (Cr; V of Y'UV) as it was coded, at its own resolution
  /// (half the luma's across and down for 4:2:0); that of an RGB picture through BT.601, at
  /// full size. Released for a picture without colour (gray formats). False when libswscale
  /// cannot convert the picture's format.
  bool convert_cr(const AVFrame& picture, cv::Mat& cr) {
    const auto format = static_cast<AVPixelFormat>(picture.format);
    const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(format);
    if (desc == nullptr) return false;
    if (desc->nb_components < 3) {
      cr.release();
      return true;
    }
    const AVComponentDescriptor& v = desc->comp[2];
    const Lines lines = first_field(picture);
    if ((desc->flags & (AV_PIX_FMT_FLAG_RGB | AV_PIX_FMT_FLAG_PAL)) == 0 && v.depth == 8 && v.shift == 0) {
      // Y'CbCr with 8-bit Cr, planar (step 1) or interleaved with Cb (NV12: step 2); of an
      // interlaced picture, the rows of its first field, each twice.
      const int width = AV_CEIL_RSHIFT(picture.width, desc->log2_chroma_w);
      const int height = AV_CEIL_RSHIFT(picture.height, desc->log2_chroma_h);
      const int rows = lines.field ? AV_CEIL_RSHIFT(lines.height, desc->log2_chroma_h) : height;
      cr.create(height, width, CV_8UC1);
      for (int y = 0; y < height; ++y) {
        const int row = lines.field ? std::min(y / 2, rows - 1) : y;
        const std::uint8_t* from =
            lines.data[v.plane] + static_cast<std::ptrdiff_t>(row) * lines.linesize[v.plane] + v.offset;
        std::uint8_t* to = cr.ptr<std::uint8_t>(y);
        for (int x = 0; x < width; ++x) to[x] = from[x * v.step];
      }
      return true;
    }
    chroma_scaler_ =
        sws_getCachedContext(chroma_scaler_, picture.width, lines.height, without_range(format), picture.width,
                             picture.height, AV_PIX_FMT_YUV444P, SWS_POINT, nullptr, nullptr, nullptr);
    if (chroma_scaler_ == nullptr) return false;
    const int* coefficients = sws_getCoefficients(SWS_CS_ITU601);  // full-range Cr, as JPEG codes it
    sws_setColorspaceDetails(chroma_scaler_, coefficients, 1, coefficients, 1, 0, 1 << 16, 1 << 16);
    const int rows = picture.height;
    padded_plane(luma_and_cb_, 2 * rows, picture.width);  // Y' above Cb; Cr straight into `cr`
    padded_plane(cr, rows, picture.width);
    std::uint8_t* planes[] = {luma_and_cb_.ptr(0), luma_and_cb_.ptr(rows), cr.ptr(0)};
    const int strides[] = {static_cast<int>(luma_and_cb_.step[0]), static_cast<int>(luma_and_cb_.step[0]),
                           static_cast<int>(cr.step[0])};
    return sws_scale(chroma_scaler_, lines.data, lines.linesize, 0, lines.height, planes, strides) == rows;
  }

  /// `plane` as a rows × cols view of a buffer that libswscale can write into: its rows a
  /// multiple of 64 bytes apart and one more such row after the last, as its SIMD code writes
  /// whole blocks, past a row's end where the row is narrower than one (13 bytes past a picture
  /// 1 pixel wide). Kept while the size holds.
  static void padded_plane(cv::Mat& plane, int rows, int cols) {
    const std::size_t stride = (static_cast<std::size_t>(cols) + 63) / 64 * 64;
    if (plane.rows == rows && plane.cols == cols && plane.type() == CV_8UC1 && plane.step[0] == stride &&
        plane.datalimit - plane.dataend >= static_cast<std::ptrdiff_t>(stride))
      return;
    plane = cv::Mat(rows + 1, static_cast<int>(stride), CV_8UC1)(cv::Rect(0, 0, cols, rows));
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
  SwsContext* chroma_scaler_ = nullptr;  // pictures whose Cr is not coded as such (RGB)
  cv::Mat luma_and_cb_;                  // their Y' and Cb, not used, kept while the size holds
};

}  // namespace lipdrive::ffmpeg
