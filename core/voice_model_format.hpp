// The .lpv voice model file format: a VoiceModel (core/voice_model.hpp) as bytes and back.
// Pure: no file I/O here (firmware_app/voice/voice_model_file.hpp reads and writes files).
//
// Layout, version 1. All integers and floats are little-endian; floats are IEEE-754 binary32.
// D = feature dimensions, I = inputs (taps · D), H = hidden units, T = 4 targets.
//
//   offset  size  field
//        0     8  magic "LPDVOICE" (ASCII, no terminator)
//        8     4  u32 format version = 1
//       12     8  u64 payload length in bytes (the bytes after the header)
//       20     4  u32 CRC-32 of the payload (zlib's crc32)
//       24        payload:
//                   u32 sample_rate, hop, window, mel_bands, cepstra; f32 min_hz, max_hz
//                   f32 margin_db, floor_quantile; u32 floor_frames, smoothing_frames, onset_frames,
//                   hangover_frames
//                   u32 past, lookahead, stride
//                   u32 H, u32 T (= 4)
//                   f32[D] feature mean, f32[D] feature scale
//                   f32[H·I] hidden weights, row-major; f32[H] hidden bias
//                   f32[T·(I+H)] output weights, row-major (open, width, protrusion, seal); f32[T] bias
//                   f32[T] centre, f32[T] gain, f32[T] rest
//                   f32 smoothing_s, f32 gate_s
//
// The file ends exactly at the end of the payload; every size is checked against the payload
// length before anything is allocated, and the model is validated (invalid_voice_model: sizes,
// finite values, and none beyond what training produces).
#pragma once

#include "core/voice_model.hpp"

#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace lipdrive {

inline constexpr std::uint32_t kVoiceFormatVersion = 1;
inline constexpr std::size_t kVoiceHeaderSize = 24;

/// A voice model file that cannot be read; the message starts with the source name.
class VoiceFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Encodes a model. Throws std::invalid_argument when it is not valid (invalid_voice_model).
std::vector<std::uint8_t> serialize_voice_model(const VoiceModel& model);

/// Decodes and validates a model; `source_name` (usually the file path) starts every error
/// message. Never reads outside `bytes`.
VoiceModel deserialize_voice_model(std::span<const std::uint8_t> bytes, const std::string& source_name);

}  // namespace lipdrive
