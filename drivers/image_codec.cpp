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

/// A picture in `format` converted from an 8-bit gray or BGR cv::Mat.
ffmpeg::Frame picture_of(const cv::Mat& image, AVPixelFormat format) {
  if (image.depth() != CV_8U || (image.channels() != 1 && image.channels() != 3) || image.empty())
    throw MediaError("only 8-bit gray or BGR images can be encoded");
  ffmpeg::Frame picture(av_frame_alloc());
  if (!picture) throw MediaError("out of memory");
  picture->format = format;
  picture->width = image.cols;
  picture->height = image.rows;
  if (av_frame_get_buffer(picture.get(), 0) < 0) throw MediaError("out of memory");
  const AVPixelFormat from = image.channels() == 1 ? AV_PIX_FMT_GRAY8 : AV_PIX_FMT_BGR24;
  // Full range out (JPEG's, and a PNG's), set before the scaler is initialised: set after, an
  // RGB -> Y'CbCr scaler keeps video range.
  SwsContext* scaler = sws_alloc_context();
  if (scaler == nullptr) throw MediaError("out of memory");
  av_opt_set_int(scaler, "srcw", image.cols, 0);
  av_opt_set_int(scaler, "srch", image.rows, 0);
  av_opt_set_int(scaler, "src_format", from, 0);
  av_opt_set_int(scaler, "dstw", image.cols, 0);
  av_opt_set_int(scaler, "dsth", image.rows, 0);
  av_opt_set_int(scaler, "dst_format", ffmpeg::LumaConverter::without_range(format), 0);
  av_opt_set_int(scaler, "sws_flags", SWS_POINT, 0);
  av_opt_set_int(scaler, "src_range", 1, 0);
  av_opt_set_int(scaler, "dst_range", 1, 0);
  if (sws_init_context(scaler, nullptr, nullptr) < 0) {
    sws_freeContext(scaler);
    throw MediaError("cannot convert the image for its encoder");
  }
  const std::uint8_t* planes[] = {image.data};
  const int strides[] = {static_cast<int>(image.step[0])};
  sws_scale(scaler, planes, strides, 0, image.rows, picture->data, picture->linesize);
  sws_freeContext(scaler);
  return picture;
}

/// One picture through the encoder named `name`: the file's bytes.
std::string encode(const char* name, AVFrame& picture, int qscale) {
  const AVCodec* encoder = avcodec_find_encoder_by_name(name);
  if (encoder == nullptr) throw MediaError(fmt::format("FFmpeg has no {} encoder", name));
  ffmpeg::Codec codec(avcodec_alloc_context3(encoder));
  ffmpeg::Packet packet(av_packet_alloc());
  if (!codec || !packet) throw MediaError("out of memory");
  codec->width = picture.width;
  codec->height = picture.height;
  codec->pix_fmt = static_cast<AVPixelFormat>(picture.format);
  codec->time_base = {1, 25};
  if (qscale > 0) {
    codec->flags |= AV_CODEC_FLAG_QSCALE;
    codec->global_quality = picture.quality = FF_QP2LAMBDA * qscale;
  }
  if (const int e = avcodec_open2(codec.get(), encoder, nullptr); e < 0)
    throw MediaError(fmt::format("cannot open the {} encoder: {}", name, error_text(e)));
  if (const int e = avcodec_send_frame(codec.get(), &picture); e < 0)
    throw MediaError(fmt::format("cannot encode {}: {}", name, error_text(e)));
  avcodec_send_frame(codec.get(), nullptr);
  std::string bytes;
  while (avcodec_receive_packet(codec.get(), packet.get()) == 0) {
    bytes.append(reinterpret_cast<const char*>(packet->data), static_cast<std::size_t>(packet->size));
    av_packet_unref(packet.get());
  }
  if (bytes.empty()) throw MediaError(fmt::format("the {} encoder gave no image", name));
  return bytes;
}

}  // namespace

struct JpegDecoder::Codec {
  ffmpeg::Codec codec;
  ffmpeg::Packet packet{av_packet_alloc()};
  ffmpeg::Frame picture{av_frame_alloc()};
  ffmpeg::LumaConverter luma;
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

bool JpegDecoder::decode(std::span<const std::uint8_t> jpeg, cv::Mat& gray) {
  Codec& c = *codec_;
  c.padded.assign(jpeg.begin(), jpeg.end());
  c.padded.resize(jpeg.size() + AV_INPUT_BUFFER_PADDING_SIZE, 0);
  c.packet->data = c.padded.data();  // not owned by the packet
  c.packet->size = static_cast<int>(jpeg.size());
  const bool decoded = avcodec_send_packet(c.codec.get(), c.packet.get()) == 0 &&
                       avcodec_receive_frame(c.codec.get(), c.picture.get()) == 0 && c.luma.convert(*c.picture, gray);
  c.packet->data = nullptr;
  c.packet->size = 0;
  av_frame_unref(c.picture.get());
  if (!decoded) gray.release();
  return decoded;
}

std::string encode_jpeg(const cv::Mat& image, int quality) {
  // libjpeg scales its tables by 5000/q % below q 50 and by 200 - 2q % above; FFmpeg's
  // quantiser scale 1..31 multiplies them in steps of about 25 %.
  const int q = std::clamp(quality, 1, 100);
  const double percent = q < 50 ? 5000.0 / q : 200.0 - 2.0 * q;
  const int qscale = std::clamp(static_cast<int>(std::lround(percent / 25.0)), 1, 31);
  ffmpeg::Frame picture = picture_of(image, AV_PIX_FMT_YUVJ420P);
  return encode("mjpeg", *picture, qscale);
}

void write_png(const std::filesystem::path& file, const cv::Mat& image) {
  std::string bytes;
  try {
    ffmpeg::Frame picture = picture_of(image, image.channels() == 1 ? AV_PIX_FMT_GRAY8 : AV_PIX_FMT_RGB24);
    bytes = encode("png", *picture, 0);
  } catch (const MediaError& e) {
    throw MediaError(fmt::format("{}: {}", file.string(), e.what()));
  }
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  if (out) out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out || !out.flush()) throw MediaError(fmt::format("{}: cannot write: {}", file.string(), std::strerror(errno)));
}

}  // namespace lipdrive
