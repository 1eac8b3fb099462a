#include "core/voice_model_format.hpp"

#include "core/byte_io.hpp"

#include <string_view>

namespace lipdrive {
namespace {

constexpr std::string_view kMagic = "LPDVOICE";

void write_floats(ByteWriter& out, const Eigen::MatrixXf& m) {
  // Row-major on disk, whatever Eigen's storage.
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    for (Eigen::Index c = 0; c < m.cols(); ++c) out.f32(m(r, c));
}

void read_floats(ByteReader<VoiceFormatError>& in, Eigen::MatrixXf& m, Eigen::Index rows, Eigen::Index cols) {
  m.resize(rows, cols);
  for (Eigen::Index r = 0; r < rows; ++r)
    for (Eigen::Index c = 0; c < cols; ++c) m(r, c) = in.f32();
}

void read_vector(ByteReader<VoiceFormatError>& in, Eigen::VectorXf& v, Eigen::Index size) {
  v.resize(size);
  in.floats(v.data(), static_cast<std::uint64_t>(size));
}

}  // namespace

std::vector<std::uint8_t> serialize_voice_model(const VoiceModel& m) {
  if (const std::string problem = invalid_voice_model(m); !problem.empty())
    throw std::invalid_argument("cannot serialize voice model: " + problem);
  ByteWriter p;
  const AudioFeatureSettings& f = m.features;
  for (int v : {f.sample_rate, f.hop, f.window, f.mel_bands, f.cepstra}) p.u32(static_cast<std::uint32_t>(v));
  p.f32(f.min_hz);
  p.f32(f.max_hz);
  const VoiceActivitySettings& a = m.activity;
  p.f32(a.margin_db);
  p.f32(a.floor_quantile);
  for (int v : {a.floor_frames, a.smoothing_frames, a.onset_frames, a.hangover_frames})
    p.u32(static_cast<std::uint32_t>(v));
  for (int v : {m.context.past, m.context.lookahead, m.context.stride}) p.u32(static_cast<std::uint32_t>(v));
  p.u32(static_cast<std::uint32_t>(m.hidden()));
  p.u32(kNumVoiceTargets);
  p.floats(m.feature_mean.data(), m.feature_mean.size());
  p.floats(m.feature_scale.data(), m.feature_scale.size());
  write_floats(p, m.hidden_weights);
  p.floats(m.hidden_bias.data(), m.hidden_bias.size());
  write_floats(p, m.weights);
  p.floats(m.bias.data(), m.bias.size());
  for (const auto* values : {&m.centre, &m.gain, &m.rest}) p.floats(values->data(), kNumVoiceTargets);
  p.f32(m.smoothing_s);
  p.f32(m.gate_s);

  ByteWriter file;
  file.bytes(kMagic);
  file.u32(kVoiceFormatVersion);
  file.u64(p.buffer().size());
  file.u32(crc32(p.buffer()));
  auto& out = file.buffer();
  out.insert(out.end(), p.buffer().begin(), p.buffer().end());
  return std::move(out);
}

VoiceModel deserialize_voice_model(std::span<const std::uint8_t> bytes, const std::string& source) {
  check_magic<VoiceFormatError>(bytes, source, kMagic, "lipdrive voice model", kVoiceHeaderSize);
  const auto version = static_cast<std::uint32_t>(get_le(bytes, 8, 4));
  if (version != kVoiceFormatVersion)
    throw VoiceFormatError(source + ": unsupported format version " + std::to_string(version) +
                           " (this build reads version " + std::to_string(kVoiceFormatVersion) + ")");
  const std::span<const std::uint8_t> payload = checked_payload<VoiceFormatError>(
      bytes, source, kVoiceHeaderSize, get_le(bytes, 12, 8), static_cast<std::uint32_t>(get_le(bytes, 20, 4)));
  ByteReader<VoiceFormatError> in(payload, source);

  VoiceModel m;
  AudioFeatureSettings& f = m.features;
  for (int* v : {&f.sample_rate, &f.hop, &f.window, &f.mel_bands, &f.cepstra}) *v = static_cast<int>(in.u32());
  f.min_hz = in.f32();
  f.max_hz = in.f32();
  VoiceActivitySettings& a = m.activity;
  a.margin_db = in.f32();
  a.floor_quantile = in.f32();
  for (int* v : {&a.floor_frames, &a.smoothing_frames, &a.onset_frames, &a.hangover_frames})
    *v = static_cast<int>(in.u32());
  for (int* v : {&m.context.past, &m.context.lookahead, &m.context.stride}) *v = static_cast<int>(in.u32());
  const std::uint32_t hidden = in.u32(), targets = in.u32();
  // Sizes are checked before anything is allocated from them.
  const auto fail = [&](const std::string& what) { throw VoiceFormatError(source + ": " + what); };
  if (const std::string problem = invalid_feature_settings(f); !problem.empty()) fail("features: " + problem);
  // The bounds first: taps() of two huge counts would overflow.
  if (m.context.stride < 1 || m.context.past < 0 || m.context.lookahead < 0 || m.context.past > 10'000 ||
      m.context.lookahead > 10'000 || m.context.taps() > kMaxVoiceTaps)
    fail("context out of range");
  if (hidden > kMaxVoiceHidden) fail(std::to_string(hidden) + " hidden units (at most 256)");
  if (targets != kNumVoiceTargets) fail(std::to_string(targets) + " targets (this build knows 4)");
  const Eigen::Index dims = f.dims(), inputs = m.inputs(), h = hidden;
  const std::uint64_t floats = 2 * dims + h * inputs + h + kNumVoiceTargets * (inputs + h + 1) + 3 * kNumVoiceTargets + 2;
  if (in.remaining() != floats * 4)
    fail("sizes inconsistent with the payload length (" + std::to_string(in.remaining()) + " bytes left for " +
         std::to_string(floats) + " numbers)");
  read_vector(in, m.feature_mean, dims);
  read_vector(in, m.feature_scale, dims);
  read_floats(in, m.hidden_weights, h, h > 0 ? inputs : 0);
  read_vector(in, m.hidden_bias, h);
  read_floats(in, m.weights, kNumVoiceTargets, inputs + h);
  read_vector(in, m.bias, kNumVoiceTargets);
  for (auto* values : {&m.centre, &m.gain, &m.rest}) in.floats(values->data(), kNumVoiceTargets);
  m.smoothing_s = in.f32();
  m.gate_s = in.f32();
  if (const std::string problem = invalid_voice_model(m); !problem.empty()) fail(problem);
  return m;
}

}  // namespace lipdrive
