#include "drivers/video_file.hpp"

#include "drivers/ffmpeg_handles.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>

extern "C" {
#include <libavutil/display.h>
}

#include <algorithm>
#include <cmath>
#include <cstdlib>

namespace lipdrive {

using ffmpeg::error_text;

namespace {

/// A display matrix's clockwise turn to the nearest quarter (av_display_rotation_get gives the
/// anticlockwise angle the matrix turns by).
DisplayOrientation orientation_of_matrix(const std::int32_t* matrix) {
  if (matrix == nullptr) return {};
  const double clockwise = -av_display_rotation_get(matrix);
  if (!std::isfinite(clockwise)) return {};
  const long quarters = std::lround(clockwise / 90.0);
  return {.turn = static_cast<Rotation>(((quarters % 4) + 4) % 4 * 90)};
}

/// An EXIF orientation tag (FFmpeg's JPEG decoder puts it in the picture's metadata as
/// "Orientation"; its PNG and TIFF decoders do not, so their tags are not read): 1 as stored, 2 mirrored, 3 turned 180°, 4 mirrored and turned 180°,
/// 5 mirrored and turned 270°, 6 turned 90°, 7 mirrored and turned 90°, 8 turned 270°
/// (clockwise); anything else as stored.
DisplayOrientation orientation_of_exif(const char* tag) {
  switch (std::strtol(tag, nullptr, 10)) {
    case 2: return {.turn = Rotation::k0, .mirrored = true};
    case 3: return {.turn = Rotation::k180};
    case 4: return {.turn = Rotation::k180, .mirrored = true};
    case 5: return {.turn = Rotation::k270, .mirrored = true};
    case 6: return {.turn = Rotation::k90};
    case 7: return {.turn = Rotation::k90, .mirrored = true};
    case 8: return {.turn = Rotation::k270};
    default: return {};
  }
}

}  // namespace

/// The demuxer, the decoder and the packet and picture they share.
struct VideoFile::Decoder {
  std::string name;
  ffmpeg::Format format;
  ffmpeg::Codec codec;
  ffmpeg::Packet packet{av_packet_alloc()};
  ffmpeg::Frame picture{av_frame_alloc()};
  ffmpeg::PictureConverter planes;
  int stream = -1;
  bool draining = false;  // the demuxer is at its end; the decoder gives back what it holds

  [[noreturn]] void fail(const std::string& reason) const { throw MediaError(fmt::format("{}: {}", name, reason)); }

  /// The decoded picture's place on the stream's timeline in periods of `frame_rate`; -1
  /// when it has no timestamp or there is no rate.
  std::int64_t timeline_index(double frame_rate) const {
    const std::int64_t pts = picture->best_effort_timestamp;
    if (pts == AV_NOPTS_VALUE || !(frame_rate > 0)) return -1;
    const AVStream* video = format->streams[stream];
    const std::int64_t start = video->start_time == AV_NOPTS_VALUE ? 0 : video->start_time;
    return std::llround(static_cast<double>(pts - start) * av_q2d(video->time_base) * frame_rate);
  }

  /// The next decoded picture; false at the end (or where a damaged file stops decoding).
  bool next() {
    for (;;) {
      const int received = avcodec_receive_frame(codec.get(), picture.get());
      if (received == 0) return true;
      if (received != AVERROR(EAGAIN)) return false;  // AVERROR_EOF, or the decoder gave up
      if (draining) return false;
      const int read = av_read_frame(format.get(), packet.get());
      if (read < 0) {
        draining = true;
        avcodec_send_packet(codec.get(), nullptr);
        continue;
      }
      // A packet the decoder rejects is skipped, as a player does; the rest still decodes.
      if (packet->stream_index == stream) avcodec_send_packet(codec.get(), packet.get());
      av_packet_unref(packet.get());
    }
  }
};

VideoFile::VideoFile(const std::filesystem::path& file) : decoder_(std::make_unique<Decoder>()) {
  Decoder& d = *decoder_;
  d.name = file.string();
  if (!d.packet || !d.picture) d.fail("out of memory");
  AVFormatContext* format = nullptr;
  if (const int e = avformat_open_input(&format, d.name.c_str(), nullptr, nullptr); e < 0)
    d.fail(fmt::format("cannot open: {}", error_text(e)));
  d.format.reset(format);
  if (const int e = avformat_find_stream_info(format, nullptr); e < 0)
    d.fail(fmt::format("cannot read the streams: {}", error_text(e)));
  const AVCodec* codec = nullptr;
  d.stream = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
  if (d.stream < 0 || codec == nullptr) d.fail("not a video or image that can be decoded");
  AVStream* video = format->streams[d.stream];
  d.codec.reset(avcodec_alloc_context3(codec));
  if (!d.codec) d.fail("out of memory");
  if (const int e = avcodec_parameters_to_context(d.codec.get(), video->codecpar); e < 0)
    d.fail(fmt::format("bad video parameters: {}", error_text(e)));
  d.codec->thread_count = 0;  // as many decoding threads as the codec can use
  if (const int e = avcodec_open2(d.codec.get(), codec, nullptr); e < 0)
    d.fail(fmt::format("cannot open the video decoder: {}", error_text(e)));

  stream_orientation_ = orientation_of_matrix(
      reinterpret_cast<const std::int32_t*>(av_stream_get_side_data(video, AV_PKT_DATA_DISPLAYMATRIX, nullptr)));

  const AVRational rate = av_guess_frame_rate(format, video, nullptr);
  frame_rate_ = rate.num > 0 && rate.den > 0 ? av_q2d(rate) : 0;
  if (video->nb_frames > 0) {
    frame_count_ = video->nb_frames;
  } else if (frame_rate_ > 0 && format->duration > 0) {
    frame_count_ = std::llround(static_cast<double>(format->duration) / AV_TIME_BASE * frame_rate_);
  }
}

VideoFile::~VideoFile() = default;

bool VideoFile::read(cv::Mat& gray, cv::Mat& cr) {
  Decoder& d = *decoder_;
  if (!d.next()) return false;
  frame_index_ = std::max(frame_index_ + 1, d.timeline_index(frame_rate_));
  const AVRational sample_aspect =
      av_guess_sample_aspect_ratio(d.format.get(), d.format->streams[d.stream], d.picture.get());
  bool converted = false;
  try {
    converted = d.planes.convert(*d.picture, gray, sample_aspect) && d.planes.convert_cr(*d.picture, cr);
  } catch (const cv::Exception& e) {  // the planes' allocation: a picture too large for memory
    av_frame_unref(d.picture.get());
    d.fail(fmt::format("cannot hold the picture's planes: {}", e.what()));
  }
  const AVDictionaryEntry* exif = av_dict_get(d.picture->metadata, "Orientation", nullptr, 0);
  orientation_ = exif != nullptr ? orientation_of_exif(exif->value) : stream_orientation_;
  av_frame_unref(d.picture.get());
  if (!converted) d.fail("cannot convert the picture to luma and chroma");
  return true;
}

DisplayOrientation read_image(const std::filesystem::path& file, cv::Mat& gray, cv::Mat& cr) {
  VideoFile image(file);
  if (!image.read(gray, cr)) throw MediaError(fmt::format("{}: cannot decode the image", file.string()));
  return image.orientation();
}

}  // namespace lipdrive
