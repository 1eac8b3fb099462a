#include "drivers/image_codec.hpp"

#include "drivers/ffmpeg_handles.hpp"

extern "C" {
#include <libavutil/opt.h>
}

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <vector>

namespace lipdrive {
namespace {

using ffmpeg::error_text;

struct ScalerFreer {
  void operator()(SwsContext* s) const { sws_freeContext(s); }
};
using Scaler = std::unique_ptr<SwsContext, ScalerFreer>;

void check_encodable(const cv::Mat& image) {
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3) || image.empty())
    throw MediaError("only 8-bit gray or BGR images can be encoded");
}

/// An empty picture in `format` of `image`'s size.
ffmpeg::Frame picture_for(const cv::Mat& image, AVPixelFormat format) {
  ffmpeg::Frame picture(av_frame_alloc());
  if (!picture) throw MediaError("out of memory");
  picture->format = format;
  picture->width = image.cols;
  picture->height = image.rows;
  if (const int e = av_frame_get_buffer(picture.get(), 0); e < 0) {
    throw MediaError(fmt::format("cannot allocate a {}x{} picture: {}", image.cols, image.rows, error_text(e)));
  }
  return picture;
}

/// A scaler from 8-bit gray or BGR images of `image`'s size to `picture`'s format.
Scaler scaler_for(const cv::Mat& image, const AVFrame& picture) {
  const AVPixelFormat from = image.channels() == 1 ? AV_PIX_FMT_GRAY8 : AV_PIX_FMT_BGR24;
  const auto to = static_cast<AVPixelFormat>(picture.format);
  // Full range out (JPEG's, and a PNG's), set before the scaler is initialised: set after, an
  // RGB -> Y'CbCr scaler keeps video range.
  Scaler scaler(sws_alloc_context());
  if (!scaler) throw MediaError("out of memory");
  av_opt_set_int(scaler.get(), "srcw", image.cols, 0);
  av_opt_set_int(scaler.get(), "srch", image.rows, 0);
  av_opt_set_int(scaler.get(), "src_format", from, 0);
  av_opt_set_int(scaler.get(), "dstw", image.cols, 0);
  av_opt_set_int(scaler.get(), "dsth", image.rows, 0);
  av_opt_set_int(scaler.get(), "dst_format", ffmpeg::PictureConverter::without_range(to), 0);
  av_opt_set_int(scaler.get(), "sws_flags", SWS_POINT, 0);
  av_opt_set_int(scaler.get(), "src_range", 1, 0);
  av_opt_set_int(scaler.get(), "dst_range", 1, 0);
  if (sws_init_context(scaler.get(), nullptr, nullptr) < 0)
    throw MediaError("cannot convert the image for its encoder");
  return scaler;
}

/// `image` into `picture` (the sizes and formats `scaler` was made for).
void convert(SwsContext& scaler, const cv::Mat& image, AVFrame& picture) {
  if (av_frame_make_writable(&picture) < 0) throw MediaError("out of memory");
  const std::uint8_t* planes[] = {image.data};
  const int strides[] = {static_cast<int>(image.step[0])};
  sws_scale(&scaler, planes, strides, 0, image.rows, picture.data, picture.linesize);
}

/// The encoder named `name`, opened for pictures like `picture` at quantiser scale `qscale`
/// (0: the encoder's own choice).
ffmpeg::Codec open_encoder(const char* name, const AVFrame& picture, int qscale) {
  const AVCodec* encoder = avcodec_find_encoder_by_name(name);
  if (encoder == nullptr) throw MediaError(fmt::format("FFmpeg has no {} encoder", name));
  ffmpeg::Codec codec(avcodec_alloc_context3(encoder));
  if (!codec) throw MediaError("out of memory");
  codec->width = picture.width;
  codec->height = picture.height;
  codec->pix_fmt = static_cast<AVPixelFormat>(picture.format);
  codec->time_base = {1, 25};
  if (qscale > 0) {
    codec->flags |= AV_CODEC_FLAG_QSCALE;
    codec->global_quality = FF_QP2LAMBDA * qscale;
  }
  if (const int e = avcodec_open2(codec.get(), encoder, nullptr); e < 0)
    throw MediaError(fmt::format("cannot open the {} encoder: {}", name, error_text(e)));
  return codec;
}

/// One picture through an opened intra-frame encoder: the image file's bytes.
std::string encode_picture(AVCodecContext& codec, AVFrame& picture, AVPacket& packet) {
  picture.quality = codec.global_quality;
  if (const int e = avcodec_send_frame(&codec, &picture); e < 0)
    throw MediaError(fmt::format("cannot encode {}: {}", codec.codec->name, error_text(e)));
  std::string bytes;
  while (avcodec_receive_packet(&codec, &packet) == 0) {
    bytes.append(reinterpret_cast<const char*>(packet.data), static_cast<std::size_t>(packet.size));
    av_packet_unref(&packet);
  }
  if (bytes.empty()) throw MediaError(fmt::format("the {} encoder gave no image", codec.codec->name));
  return bytes;
}

}  // namespace

struct JpegDecoder::Codec {
  ffmpeg::Codec codec;
  ffmpeg::Packet packet{av_packet_alloc()};
  ffmpeg::Frame picture{av_frame_alloc()};
  ffmpeg::PictureConverter planes;
  std::vector<std::uint8_t> padded;  // the image and the zero bytes FFmpeg's decoders may read past it
};

JpegDecoder::JpegDecoder() : codec_(std::make_unique<Codec>()) {
  const AVCodec* decoder = avcodec_find_decoder(AV_CODEC_ID_MJPEG);
  if (decoder == nullptr) throw MediaError("FFmpeg has no JPEG decoder");
  codec_->codec.reset(avcodec_alloc_context3(decoder));
  if (!codec_->codec || !codec_->packet || !codec_->picture) throw MediaError("out of memory");
  if (const int e = avcodec_open2(codec_->codec.get(), decoder, nullptr); e < 0)
    throw MediaError(fmt::format("cannot open the JPEG decoder: {}", error_text(e)));
}

JpegDecoder::~JpegDecoder() = default;

bool JpegDecoder::decode(std::span<const std::uint8_t> jpeg, cv::Mat& gray, cv::Mat& cr) {
  Codec& c = *codec_;
  c.padded.assign(jpeg.begin(), jpeg.end());
  c.padded.resize(jpeg.size() + AV_INPUT_BUFFER_PADDING_SIZE, 0);
  c.packet->data = c.padded.data();  // not owned by the packet
  c.packet->size = static_cast<int>(jpeg.size());
  const bool decoded = avcodec_send_packet(c.codec.get(), c.packet.get()) == 0 &&
                       avcodec_receive_frame(c.codec.get(), c.picture.get()) == 0 &&
                       c.planes.convert(*c.picture, gray, c.picture->sample_aspect_ratio) &&
                       c.planes.convert_cr(*c.picture, cr);
  c.packet->data = nullptr;
  c.packet->size = 0;
  av_frame_unref(c.picture.get());
  if (!decoded) {
    gray.release();
    cr.release();
  }
  return decoded;
}

struct JpegEncoder::Codec {
  int qscale = 1;
  int width = 0, height = 0, channels = 0;  // of the images the objects below were made for
  ffmpeg::Frame picture;
  Scaler scaler;
  ffmpeg::Codec codec;
  ffmpeg::Packet packet{av_packet_alloc()};
};

JpegEncoder::JpegEncoder(int quality) : codec_(std::make_unique<Codec>()) {
  // libjpeg scales its tables by 5000/q % below q 50 and by 200 - 2q % above; FFmpeg's
  // quantiser scale 1..31 multiplies them in steps of about 25 %.
  const int q = std::clamp(quality, 1, 100);
  const double percent = q < 50 ? 5000.0 / q : 200.0 - 2.0 * q;
  codec_->qscale = std::clamp(static_cast<int>(std::lround(percent / 25.0)), 1, 31);
  if (!codec_->packet) throw MediaError("out of memory");
}

JpegEncoder::~JpegEncoder() = default;

std::string JpegEncoder::encode(const cv::Mat& image) {
  check_encodable(image);
  Codec& c = *codec_;
  if (image.cols != c.width || image.rows != c.height || image.channels() != c.channels || !c.codec) {
    c.codec.reset();
    c.picture = picture_for(image, AV_PIX_FMT_YUVJ420P);
    c.scaler = scaler_for(image, *c.picture);
    c.codec = open_encoder("mjpeg", *c.picture, c.qscale);
    c.width = image.cols;
    c.height = image.rows;
    c.channels = image.channels();
  }
  convert(*c.scaler, image, *c.picture);
  return encode_picture(*c.codec, *c.picture, *c.packet);
}

void write_png(const std::filesystem::path& file, const cv::Mat& image) {
  std::string bytes;
  try {
    check_encodable(image);
    ffmpeg::Frame picture = picture_for(image, image.channels() == 1 ? AV_PIX_FMT_GRAY8 : AV_PIX_FMT_RGB24);
    convert(*scaler_for(image, *picture), image, *picture);
    ffmpeg::Codec codec = open_encoder("png", *picture, 0);
    ffmpeg::Packet packet(av_packet_alloc());
    if (!packet) throw MediaError("out of memory");
    bytes = encode_picture(*codec, *picture, *packet);
  } catch (const MediaError& e) {
    throw MediaError(fmt::format("{}: {}", file.string(), e.what()));
  }
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (out) out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out || !out.flush()) throw MediaError(fmt::format("{}: cannot write: {}", file.string(), std::strerror(errno)));
}

}  // namespace lipdrive
