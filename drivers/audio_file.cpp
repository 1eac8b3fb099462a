#include "drivers/audio_file.hpp"

#include "drivers/ffmpeg_handles.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

extern "C" {
#include <libavutil/opt.h>
#include <libswresample/swresample.h>
}

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>

namespace lipdrive {
namespace {

using ffmpeg::error_text;

struct ResamplerFreer {
  void operator()(SwrContext* s) const { swr_free(&s); }
};

/// A channel layout that frees what it holds (a custom layout's channel map).
struct OwnedLayout {
  AVChannelLayout layout{};
  OwnedLayout() = default;
  OwnedLayout(const OwnedLayout&) = delete;
  OwnedLayout& operator=(const OwnedLayout&) = delete;
  ~OwnedLayout() { av_channel_layout_uninit(&layout); }
};

double stream_start_s(const AVStream* stream) {
  if (stream->start_time == AV_NOPTS_VALUE) return 0;
  return static_cast<double>(stream->start_time) * av_q2d(stream->time_base);
}

/// One file's decoder and resampler; decode() appends the mono samples.
class TrackDecoder {
 public:
  /// The most the track's timestamps and its samples may disagree before the samples are
  /// moved to their timestamps (codecs' frames and containers' rounding stay well under it).
  static constexpr double kMaxDrift_s = 0.02;

  TrackDecoder(const std::filesystem::path& file, int sample_rate) : name_(file.string()), rate_(sample_rate) {
    AVFormatContext* format = nullptr;
    if (const int e = avformat_open_input(&format, name_.c_str(), nullptr, nullptr); e < 0)
      fail(fmt::format("cannot open: {}", error_text(e)));
    format_.reset(format);
    if (const int e = avformat_find_stream_info(format, nullptr); e < 0)
      fail(fmt::format("cannot read the streams: {}", error_text(e)));
    const AVCodec* codec = nullptr;
    stream_ = av_find_best_stream(format, AVMEDIA_TYPE_AUDIO, -1, -1, &codec, 0);
    if (stream_ < 0) fail("no audio track (the clip is video-only)");
    if (!codec) fail("no decoder for the audio track");
    const AVStream* audio = format->streams[stream_];
    const int video = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
    start_s_ = stream_start_s(audio) - (video >= 0 ? stream_start_s(format->streams[video]) : 0.0);
    time_base_ = audio->time_base;
    first_pts_ = audio->start_time == AV_NOPTS_VALUE ? 0 : audio->start_time;

    codec_.reset(avcodec_alloc_context3(codec));
    if (!codec_) fail("out of memory");
    if (const int e = avcodec_parameters_to_context(codec_.get(), audio->codecpar); e < 0)
      fail(fmt::format("bad audio parameters: {}", error_text(e)));
    if (const int e = avcodec_open2(codec_.get(), codec, nullptr); e < 0)
      fail(fmt::format("cannot open the audio decoder: {}", error_text(e)));

    open_resampler(codec_->ch_layout, codec_->sample_fmt, codec_->sample_rate);
  }

  DecodedAudio decode() {
    DecodedAudio out;
    out.sample_rate = rate_;
    out.source_rate = codec_->sample_rate;
    out.start_s = start_s_;
    const ffmpeg::Packet packet(av_packet_alloc());
    const ffmpeg::Frame frame(av_frame_alloc());
    if (!packet || !frame) fail("out of memory");
    for (;;) {
      const int e = av_read_frame(format_.get(), packet.get());
      if (e == AVERROR_EOF) break;
      if (e < 0) fail(fmt::format("cannot read: {}", error_text(e)));
      if (packet->stream_index == stream_) send(packet.get(), frame.get(), out);
      av_packet_unref(packet.get());
    }
    send(nullptr, frame.get(), out);  // drain the decoder
    convert(nullptr, 0, out);         // and the resampler
    return out;
  }

 private:
  [[noreturn]] void fail(const std::string& reason) const {
    throw AudioSourceError(fmt::format("{}: {}", name_, reason));
  }

  /// A resampler from this channel layout, sample format and rate to planar float at rate_ (the
  /// channels are averaged in convert()), whose output starts where the samples so far end.
  void open_resampler(const AVChannelLayout& layout, AVSampleFormat format, int sample_rate) {
    if (layout.nb_channels < 1) fail("the audio track has no channels");
    if (sample_rate < kMinAudioSampleRate)
      fail(fmt::format("sound at {} Hz; at least {} Hz (the lowest speech is recorded at)", sample_rate,
                       kMinAudioSampleRate));
    if (const int e = av_channel_layout_copy(&in_layout_.layout, &layout); e < 0)
      fail(fmt::format("cannot resample: {}", error_text(e)));
    SwrContext* resampler = nullptr;
    if (const int e = swr_alloc_set_opts2(&resampler, &in_layout_.layout, AV_SAMPLE_FMT_FLTP, rate_, &in_layout_.layout,
                                          format, sample_rate, 0, nullptr);
        e < 0)
      fail(fmt::format("cannot resample: {}", error_text(e)));
    resampler_.reset(resampler);
    // Samples placed by their timestamps: where the track's timestamps run ahead of its samples
    // by more than kMaxDrift_s (a recorder lost some), libswresample fills the gap with
    // silence; where they fall behind (overlap), it drops the excess. Nothing is stretched.
    av_opt_set_double(resampler, "min_comp", kMaxDrift_s, 0);
    av_opt_set_double(resampler, "min_hard_comp", kMaxDrift_s, 0);
    if (const int e = swr_init(resampler); e < 0) fail(fmt::format("cannot resample: {}", error_text(e)));
    in_format_ = format;
    in_rate_ = sample_rate;
    channels_ = layout.nb_channels;
  }

  void send(const AVPacket* packet, AVFrame* frame, DecodedAudio& out) {
    // A damaged packet is skipped, as a player skips it; the samples after it keep their
    // timestamps, so the gap is silence and nothing later moves.
    if (const int e = avcodec_send_packet(codec_.get(), packet); e == AVERROR_INVALIDDATA)
      ++out.damaged_packets;
    else if (e < 0 && e != AVERROR_EOF)
      fail(fmt::format("cannot decode the audio: {}", error_text(e)));
    for (;;) {
      const int e = avcodec_receive_frame(codec_.get(), frame);
      if (e == AVERROR(EAGAIN) || e == AVERROR_EOF) return;
      if (e == AVERROR_INVALIDDATA) {
        ++out.damaged_packets;
        continue;
      }
      if (e < 0) fail(fmt::format("cannot decode the audio: {}", error_text(e)));
      // A track whose channels, sample format or rate change (clips joined end to end): what the
      // last resampler holds goes out, and a new one takes the frames from here.
      if (frame->format != in_format_ || frame->sample_rate != in_rate_ ||
          av_channel_layout_compare(&frame->ch_layout, &in_layout_.layout) != 0) {
        convert(nullptr, 0, out);
        origin_ = static_cast<std::int64_t>(out.samples.size());
        open_resampler(frame->ch_layout, static_cast<AVSampleFormat>(frame->format), frame->sample_rate);
      }
      // The frame's place after the track's first sample, less where this resampler's output
      // began, in libswresample's units of 1 / (input rate × output rate) seconds.
      const std::int64_t pts = frame->best_effort_timestamp;
      const std::int64_t units_per_tick = static_cast<std::int64_t>(time_base_.num) * in_rate_ * rate_;
      swr_next_pts(resampler_.get(),
                   pts == AV_NOPTS_VALUE
                       ? INT64_MIN
                       : av_rescale(pts - first_pts_, units_per_tick, time_base_.den) - origin_ * in_rate_);
      convert(const_cast<const std::uint8_t**>(frame->extended_data), frame->nb_samples, out);
      av_frame_unref(frame);
    }
  }

  void convert(const std::uint8_t** in, int count, DecodedAudio& out) {
    const int room = swr_get_out_samples(resampler_.get(), count);
    if (room <= 0) return;
    planes_.resize(static_cast<std::size_t>(channels_));
    std::vector<std::uint8_t*> pointers;
    for (auto& plane : planes_) {
      plane.resize(static_cast<std::size_t>(room));
      pointers.push_back(reinterpret_cast<std::uint8_t*>(plane.data()));
    }
    const int made = swr_convert(resampler_.get(), pointers.data(), room, in, count);
    if (made < 0) fail(fmt::format("cannot resample: {}", error_text(made)));
    const float scale = 1.0f / static_cast<float>(channels_);
    for (int i = 0; i < made; ++i) {
      float sum = 0;
      for (const auto& plane : planes_) sum += plane[static_cast<std::size_t>(i)];
      out.samples.push_back(sum * scale);
    }
  }

  std::string name_;
  int rate_;
  ffmpeg::Format format_;
  ffmpeg::Codec codec_;
  std::unique_ptr<SwrContext, ResamplerFreer> resampler_;
  // What the resampler takes, and the output sample its output began at.
  OwnedLayout in_layout_;
  AVSampleFormat in_format_ = AV_SAMPLE_FMT_NONE;
  int in_rate_ = 0;
  std::int64_t origin_ = 0;
  int stream_ = -1;
  int channels_ = 0;
  double start_s_ = 0;
  AVRational time_base_{1, 1};
  std::int64_t first_pts_ = 0;  // the track's start, in time_base_
  std::vector<std::vector<float>> planes_;
};

}  // namespace

DecodedAudio decode_audio(const std::filesystem::path& file, int sample_rate) {
  if (sample_rate < kMinAudioSampleRate || sample_rate > kMaxAudioSampleRate)
    throw AudioSourceError(fmt::format("{}: sample rate {} Hz out of range", file.string(), sample_rate));
  DecodedAudio audio = TrackDecoder(file, sample_rate).decode();
  if (audio.damaged_packets > 0)
    spdlog::warn("{}: {} damaged audio packet{} skipped (silence in their place)", file.string(), audio.damaged_packets,
                 audio.damaged_packets == 1 ? "" : "s");
  return audio;
}

struct WavWriter::Muxer {
  struct Closer {
    void operator()(AVFormatContext* c) const {
      if (c->pb != nullptr) avio_closep(&c->pb);
      avformat_free_context(c);
    }
  };
  std::unique_ptr<AVFormatContext, Closer> format;
  ffmpeg::Packet packet{av_packet_alloc()};
  bool open = false;  // the header is written and the trailer is not
};

WavWriter::WavWriter(const std::filesystem::path& file, int sample_rate)
    : muxer_(std::make_unique<Muxer>()), name_(file.string()) {
  const auto fail = [&](const std::string& why) { throw AudioSourceError(fmt::format("{}: {}", name_, why)); };
  AVFormatContext* format = nullptr;
  if (avformat_alloc_output_context2(&format, nullptr, "wav", name_.c_str()) < 0 || format == nullptr)
    fail("FFmpeg has no WAV muxer");
  muxer_->format.reset(format);
  AVStream* stream = avformat_new_stream(format, nullptr);
  if (stream == nullptr || !muxer_->packet) fail("out of memory");
  AVCodecParameters& p = *stream->codecpar;
  p.codec_type = AVMEDIA_TYPE_AUDIO;
  p.codec_id = AV_CODEC_ID_PCM_S16LE;
  p.sample_rate = sample_rate;
  av_channel_layout_default(&p.ch_layout, 1);
  p.bits_per_coded_sample = 16;
  p.block_align = 2;
  p.bit_rate = 16LL * sample_rate;
  stream->time_base = {1, sample_rate};
  if (const int e = avio_open(&format->pb, name_.c_str(), AVIO_FLAG_WRITE); e < 0)
    fail(fmt::format("cannot create: {}", error_text(e)));
  if (const int e = avformat_write_header(format, nullptr); e < 0)
    fail(fmt::format("cannot write the header: {}", error_text(e)));
  muxer_->open = true;
}

WavWriter::~WavWriter() {
  try {
    close();
  } catch (const AudioSourceError&) {  // close() is the place to hear about it
  }
}

void WavWriter::write(std::span<const float> samples) {
  std::array<std::int16_t, 1024> pcm{};
  while (!samples.empty()) {
    const std::size_t count = std::min(samples.size(), pcm.size());
    for (std::size_t i = 0; i < count; ++i)
      pcm[i] = static_cast<std::int16_t>(std::lround(std::clamp(samples[i], -1.0f, 1.0f) * 32767.0f));
    write_pcm(pcm.data(), static_cast<int>(count));
    samples = samples.subspan(count);
  }
}

void WavWriter::write_silence(std::int64_t count) {
  const std::array<std::int16_t, 1024> zeros{};
  for (; count > 0; count -= static_cast<std::int64_t>(zeros.size()))
    write_pcm(zeros.data(), static_cast<int>(std::min<std::int64_t>(count, zeros.size())));
}

void WavWriter::write_pcm(const std::int16_t* pcm, int count) {
  if (!muxer_->open) throw AudioSourceError(fmt::format("{}: written after it was closed", name_));
  AVPacket& packet = *muxer_->packet;
  // Not reference-counted: the muxer writes the bytes before av_write_frame returns.
  packet.data = reinterpret_cast<std::uint8_t*>(const_cast<std::int16_t*>(pcm));
  packet.size = 2 * count;
  packet.stream_index = 0;
  packet.pts = packet.dts = samples_;
  packet.duration = count;
  const int e = av_write_frame(muxer_->format.get(), &packet);
  packet.data = nullptr;
  packet.size = 0;
  if (e < 0) throw AudioSourceError(fmt::format("{}: cannot write: {}", name_, error_text(e)));
  samples_ += count;
}

void WavWriter::close() {
  if (!muxer_->open) return;
  muxer_->open = false;
  AVFormatContext* format = muxer_->format.get();
  const int trailer = av_write_trailer(format);
  avio_flush(format->pb);
  const int error = format->pb->error;
  avio_closep(&format->pb);
  if (trailer < 0 || error < 0)
    throw AudioSourceError(
        fmt::format("{}: cannot finish the file: {}", name_, error_text(trailer < 0 ? trailer : error)));
}

}  // namespace lipdrive
