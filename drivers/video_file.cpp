#include "drivers/video_file.hpp"

#include "drivers/ffmpeg_handles.hpp"
#include "drivers/ffmpeg_log.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>

extern "C" {
#include <libavutil/display.h>
#include <libavutil/parseutils.h>
}

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string_view>
#include <utility>

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

/// The frames the file states exactly that its picture shows, in periods of `rate`; 0 where it
/// states none. Its declared frames (an AVI's header says so even where its index is lost), no
/// more than its duration covers in an MP4 or QuickTime file (whose edit list may leave frames
/// it holds unshown: a cut with -c copy between keyframes), rounded down: a frame it covers only
/// in part may not be shown. Not the file's length, which its sound may outlast, nor the
/// duration FFmpeg estimates from timestamps where a file states none (an MPEG program or
/// transport stream: it may be a frame's).
std::int64_t stated_frames(const AVFormatContext& format, const AVStream& video, AVRational rate) {
  if (video.nb_frames <= 0) return 0;
  const bool edited = std::string_view(format.iformat->name).starts_with("mov,");
  return edited && rate.num > 0 && rate.den > 0 && video.duration > 0
             ? std::min(video.nb_frames,
                        av_rescale_q_rnd(video.duration, video.time_base, av_inv_q(rate), AV_ROUND_DOWN))
             : video.nb_frames;
}

/// Where a Matroska track's DURATION tag says its picture ends, in seconds from its start; none
/// without one. A time, not a count of frames at the one rate the file states: a variable-rate
/// clip's frames, or a last frame shown longer than a period, do not fill that rate's slots.
std::optional<double> stated_end_s(const AVStream& video) {
  const AVDictionaryEntry* tag = av_dict_get(video.metadata, "DURATION", nullptr, AV_DICT_IGNORE_SUFFIX);
  std::int64_t end = 0;
  if (tag == nullptr || av_parse_time(&end, tag->value, 1) != 0) return std::nullopt;
  const std::int64_t start =
      video.start_time == AV_NOPTS_VALUE ? 0 : av_rescale_q(video.start_time, video.time_base, AV_TIME_BASE_Q);
  return static_cast<double>(std::max<std::int64_t>(end - start, 0)) / AV_TIME_BASE;
}

/// The frames missing between a frame at `previous_s` shown for `shown_for_s` and the next one at
/// `time_s`, at `rate` frames a second (rounded: timestamps are coded to a clock tick).
std::int64_t frames_missing_between(double previous_s, double shown_for_s, double time_s, double rate) {
  return std::max<std::int64_t>(std::llround((time_s - previous_s - shown_for_s) * rate), 0);
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
  bool draining = false;    // the demuxer is at its end; the decoder gives back what it holds
  bool packet_cut = false;  // the picture's packet read last came short of the size the file gave it
  bool concealed = false;   // the decoder patched over damage in the picture received last
  std::int64_t refused = 0;  // the picture's packets the decoder refused: each a frame lost
  std::string damage;       // what went wrong where the pictures ended; empty at a clean end

  [[noreturn]] void fail(const std::string& reason) const { throw MediaError(fmt::format("{}: {}", name, reason)); }

  /// Refuses pictures larger than kMaxPictureSide on a side.
  void check_size(int width, int height) const {
    if (width > kMaxPictureSide || height > kMaxPictureSide)
      fail(fmt::format("pictures of {}×{} pixels; at most {} on a side", width, height, kMaxPictureSide));
  }

  /// The decoded picture's time from the stream's start in seconds; none without a timestamp.
  std::optional<double> picture_time_s() const {
    const std::int64_t pts = picture->best_effort_timestamp;
    if (pts == AV_NOPTS_VALUE) return std::nullopt;
    const AVStream* video = format->streams[stream];
    const std::int64_t start = video->start_time == AV_NOPTS_VALUE ? 0 : video->start_time;
    return static_cast<double>(pts - start) * av_q2d(video->time_base);
  }

  /// How long the decoded picture is shown in seconds (a picture repeated by pulldown longer than
  /// a period); none where the stream does not say.
  std::optional<double> picture_duration_s() const {
    if (picture->pkt_duration <= 0) return std::nullopt;
    return static_cast<double>(picture->pkt_duration) * av_q2d(format->streams[stream]->time_base);
  }

  /// The next decoded picture; false at the end (or where a damaged file stops decoding, saying
  /// why in `damage`).
  bool next() {
    for (;;) {
      const int received = avcodec_receive_frame(codec.get(), picture.get());
      if (received == 0) {
        concealed = picture->decode_error_flags != 0;
        return true;
      }
      if (received != AVERROR(EAGAIN)) {
        if (received != AVERROR_EOF)
          damage = fmt::format("cannot decode further: {}", error_text(received));
        else if (damage.empty() && concealed)
          damage = "the file ends inside its last picture";
        return false;
      }
      if (draining) return false;
      const int read = av_read_frame(format.get(), packet.get());
      if (read < 0) {
        // The file ending inside a packet is a file cut short, in any container. Where the
        // demuxer's packets go through a parser (an MPEG program or transport stream), the cut
        // packet's mark does not reach us: the decoder, patching over its last picture, tells.
        if (read != AVERROR_EOF)
          damage = fmt::format("cannot read further: {}", error_text(read));
        else if (packet_cut)
          damage = "the file ends inside a packet";
        draining = true;
        avcodec_send_packet(codec.get(), nullptr);
        continue;
      }
      // A packet the decoder rejects is skipped, as a player does; the rest still decodes. Only
      // the picture's packets tell its damage: a file cut inside the sound that runs on after
      // its last frame has shown all of its picture.
      if (packet->stream_index == stream) {
        packet_cut = (packet->flags & AV_PKT_FLAG_CORRUPT) != 0;
        refused += avcodec_send_packet(codec.get(), packet.get()) < 0;
      }
      av_packet_unref(packet.get());
    }
  }
};

VideoFile::VideoFile(const std::filesystem::path& file) : decoder_(std::make_unique<Decoder>()) {
  Decoder& d = *decoder_;
  d.name = file.string();
  if (!d.packet || !d.picture) d.fail("out of memory");
  AVFormatContext* format = nullptr;
  take_ffmpeg_error();
  if (const int e = avformat_open_input(&format, d.name.c_str(), nullptr, nullptr); e < 0) {
    // The demuxer's own reason where it logged one: its return code may say little.
    const std::string reason = take_ffmpeg_error();
    d.fail(fmt::format("cannot open: {}", reason.empty() ? error_text(e) : reason));
  }
  d.format.reset(format);
  // The probe decodes a picture where the container does not state its size (a PNG, a JPEG):
  // it is held to the same size, so an oversized still is refused without being decoded.
  constexpr std::int64_t kMaxPixels = static_cast<std::int64_t>(kMaxPictureSide) * kMaxPictureSide;
  std::vector<AVDictionary*> probe_options(format->nb_streams, nullptr);
  for (AVDictionary*& options : probe_options) av_dict_set_int(&options, "max_pixels", kMaxPixels, 0);
  take_ffmpeg_error();
  const int probed = avformat_find_stream_info(format, probe_options.data());
  for (AVDictionary*& options : probe_options) av_dict_free(&options);
  if (probed < 0) d.fail(fmt::format("cannot read the streams: {}", error_text(probed)));
  const std::string probe_error = take_ffmpeg_error();
  const AVCodec* codec = nullptr;
  d.stream = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
  if (d.stream < 0 || codec == nullptr) d.fail("not a video or image that can be decoded");
  AVStream* video = format->streams[d.stream];
  // A picture the probe refused to decode (larger than the limit) leaves its size unknown.
  if (video->codecpar->width <= 0 || video->codecpar->height <= 0)
    d.fail(fmt::format("cannot read the picture's size: {} (at most {} on a side)",
                       probe_error.empty() ? "the probe found none" : probe_error, kMaxPictureSide));
  d.check_size(video->codecpar->width, video->codecpar->height);
  d.codec.reset(avcodec_alloc_context3(codec));
  if (!d.codec) d.fail("out of memory");
  if (const int e = avcodec_parameters_to_context(d.codec.get(), video->codecpar); e < 0)
    d.fail(fmt::format("bad video parameters: {}", error_text(e)));
  d.codec->thread_count = 0;  // as many decoding threads as the codec can use
  // A later picture larger than the first (a stream whose size changes): one over this many
  // pixels the decoder refuses before it is allocated, and its packet is skipped as a damaged
  // one (FFmpeg's warning in the log); one within them read() refuses.
  d.codec->max_pixels = kMaxPixels;
  if (const int e = avcodec_open2(d.codec.get(), codec, nullptr); e < 0)
    d.fail(fmt::format("cannot open the video decoder: {}", error_text(e)));

  stream_orientation_ = orientation_of_matrix(
      reinterpret_cast<const std::int32_t*>(av_stream_get_side_data(video, AV_PKT_DATA_DISPLAYMATRIX, nullptr)));

  const AVRational rate = av_guess_frame_rate(format, video, nullptr);
  frame_rate_ = rate.num > 0 && rate.den > 0 ? av_q2d(rate) : 0;
  if (format->duration > 0) length_s_ = static_cast<double>(format->duration) / AV_TIME_BASE;
  if (video->nb_frames > 0) {
    frame_count_ = video->nb_frames;
  } else if (frame_rate_ > 0) {
    frame_count_ = std::llround(length_s_ * frame_rate_);
  }
  const std::string_view container = format->iformat->name;
  gaps_are_losses_ = container == "mpeg" || container == "mpegts";
  stated_frames_ = stated_frames(*format, *video, rate);
  if (stated_frames_ == 0) stated_end_s_ = stated_end_s(*video);
}

VideoFile::~VideoFile() = default;

const std::string& VideoFile::damage() const { return decoder_->damage; }

void VideoFile::judge_end() {
  Decoder& d = *decoder_;
  // How far the frames reached on the file's timeline: slots a recorder left empty are not
  // missing. Against a stated end, the last frame lasts as long as the gap before it (a
  // period where unknown), and may be shown up to a period longer.
  const double period_s = frame_rate_ > 0 ? 1 / frame_rate_ : 0;
  const double reached_s = frame_time_s_
                               ? *frame_time_s_ + (previous_time_s_ ? *frame_time_s_ - *previous_time_s_ : period_s)
                               : static_cast<double>(frame_index_ + 1) * period_s;
  // The frames short of where the file says its picture ends; none where it does not say.
  std::optional<std::int64_t> short_of_end;
  if (stated_frames_ > 0)
    short_of_end = std::max<std::int64_t>(stated_frames_ - (frame_index_ + 1), 0);
  else if (stated_end_s_ && period_s > 0)
    short_of_end = reached_s + period_s < *stated_end_s_ ? std::llround((*stated_end_s_ - reached_s) / period_s) : 0;
  // The reading itself failed (a cut, a demuxer's or decoder's error): what came after is not
  // known unless the file says how long it is.
  const bool ended_early = !d.damage.empty();
  if (d.damage.empty() && short_of_end.value_or(0) > 0)
    d.damage = stated_frames_ > 0 ? fmt::format("the file states {} frames", stated_frames_)
                                  : fmt::format("the file states its picture lasts {:.3f} s", *stated_end_s_);
  else if (d.damage.empty() && lost_in_gaps_ > 0)
    d.damage = fmt::format("{} frames are missing where its timestamps jump (the first gap after {:.3f} s)",
                           lost_in_gaps_, *first_gap_s_);
  if (!d.damage.empty() && (short_of_end || !ended_early))
    lost_frames_ = short_of_end.value_or(0) + lost_in_gaps_ + d.refused;
}

bool VideoFile::read(cv::Mat& gray, cv::Mat& cr) {
  Decoder& d = *decoder_;
  if (!d.next()) {
    judge_end();
    return false;
  }
  d.check_size(d.picture->width, d.picture->height);
  previous_time_s_ = frame_time_s_;
  frame_time_s_ = d.picture_time_s();
  const double previous_shown_for_s = std::exchange(shown_for_s_, d.picture_duration_s().value_or(1 / frame_rate_));
  if (gaps_are_losses_ && previous_time_s_ && frame_time_s_ && frame_rate_ > 0) {
    const std::int64_t missing =
        frames_missing_between(*previous_time_s_, previous_shown_for_s, *frame_time_s_, frame_rate_);
    if (missing > 0 && !first_gap_s_) first_gap_s_ = previous_time_s_;
    lost_in_gaps_ += missing;
  }
  const std::int64_t slot = frame_time_s_ && frame_rate_ > 0 ? std::llround(*frame_time_s_ * frame_rate_) : -1;
  frame_index_ = std::max(frame_index_ + 1, slot);
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
