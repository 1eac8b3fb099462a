#include "core/model_format.hpp"

#include "core/byte_io.hpp"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <optional>
#include <string_view>

namespace lipdrive {
namespace {

constexpr std::string_view kMagic = "LPDMODEL";

std::uint32_t crc_of_floats(std::uint32_t crc, const float* data, Eigen::Index count) {
  return crc32({reinterpret_cast<const std::uint8_t*>(data), static_cast<std::size_t>(count) * sizeof(float)}, crc);
}

// --- writing -------------------------------------------------------------

void check_serializable(const MorphableModel& m) {
  const auto fail = [](const std::string& what) { throw std::invalid_argument("cannot serialize model: " + what); };
  if (m.mean.size() % 3 != 0) fail("mean size is not a multiple of 3");
  if (m.basis.rows() != m.mean.size() || m.basis.cols() != m.stddev.size()) fail("basis is not 3N x K");
  if (m.pose_coefficients.rows() != m.stddev.size() ||
      m.pose_coefficients.cols() != static_cast<Eigen::Index>(m.pose_names.size()))
    fail("pose_coefficients is not K x P");
  for (const auto& name : m.pose_names)
    if (name.size() > std::numeric_limits<std::uint16_t>::max()) fail("pose name longer than 65535 bytes");
  if (m.has_expressions() && (m.expressions.rows() != m.mean.size() || m.expressions.cols() != m.num_expressions()))
    fail("expressions is not 3N x E");
  for (const auto& name : m.expression_names)
    if (name.size() > std::numeric_limits<std::uint16_t>::max()) fail("expression name longer than 65535 bytes");
}

// --- reading -------------------------------------------------------------

struct Header {
  std::uint32_t version, vertices, components, triangles, poses, expressions = 0;
  std::uint64_t payload_length, inflated_length = 0;
  std::uint32_t checksum;
};

/// a * b + c * d + ... for the (count, bytes per value) pairs, or nullopt on 64-bit overflow.
std::optional<std::uint64_t> sum_of_products(std::initializer_list<std::pair<std::uint64_t, std::uint64_t>> terms) {
  std::uint64_t total = 0;
  for (const auto& [count, size] : terms) {
    std::uint64_t bytes = 0;
    if (__builtin_mul_overflow(count, size, &bytes) || __builtin_add_overflow(total, bytes, &total))
      return std::nullopt;
  }
  return total;
}

// Payload bytes the counts require (each name counted by its 2-byte length only), or nullopt
// when the sizes overflow 64 bits. Version 1 stores the basis as f32, version 2 as f32 scale +
// i16 per column and adds the expressions.
std::optional<std::uint64_t> fixed_payload_bytes(const Header& h) {
  const std::uint64_t n3 = 3ull * h.vertices;
  std::uint64_t basis_values = 0, coefficient_values = 0, expression_values = 0;
  if (__builtin_mul_overflow(n3, std::uint64_t{h.components}, &basis_values)) return std::nullopt;
  if (__builtin_mul_overflow(std::uint64_t{h.components}, std::uint64_t{h.poses}, &coefficient_values))
    return std::nullopt;
  if (__builtin_mul_overflow(n3, std::uint64_t{h.expressions}, &expression_values)) return std::nullopt;
  if (h.version == kModelFormatVersion)
    return sum_of_products({{1, 4},
                            {n3, 4},
                            {h.components, 4},
                            {basis_values, 4},
                            {3ull * h.triangles, 4},
                            {kNumLandmarks, 4},
                            {coefficient_values, 4},
                            {h.poses, 2}});
  return sum_of_products({{1, 4},
                          {n3, 4},
                          {h.components, 4},
                          {h.components, 4},
                          {basis_values, 2},
                          {3ull * h.triangles, 4},
                          {kNumLandmarks, 4},
                          {coefficient_values, 4},
                          {h.poses, 2},
                          {h.expressions, 2},
                          {h.expressions, 4},
                          {expression_values, 2}});
}

// Checks that the payload fills the file exactly and matches its checksum.
void check_payload(std::span<const std::uint8_t> bytes, std::size_t header_size, const Header& h,
                   const std::string& source) {
  checked_payload<ModelFormatError>(bytes, source, header_size, h.payload_length, h.checksum);
}

// Checks the counts against the (inflated) payload length they must fit in.
void check_counts(const Header& h, std::uint64_t payload_length, const std::string& source) {
  const auto fixed = fixed_payload_bytes(h);
  if (!fixed || *fixed > payload_length)
    throw ModelFormatError(source + ": sizes inconsistent with the payload length (" + std::to_string(h.vertices) +
                           " vertices, " + std::to_string(h.components) + " components, " +
                           std::to_string(h.triangles) + " triangles, " + std::to_string(h.poses) + " poses, " +
                           std::to_string(h.expressions) + " expressions do not fit in " +
                           std::to_string(payload_length) + " bytes)");
  if (h.vertices == 0) throw ModelFormatError(source + ": model has no vertices");
  if (h.components == 0) throw ModelFormatError(source + ": model has no components");
  if (std::uint64_t{h.components} > 3ull * h.vertices)
    throw ModelFormatError(source + ": " + std::to_string(h.components) +
                           " components exceed 3N = " + std::to_string(3ull * h.vertices));
}

// Reads and checks the header and the payload's extent and checksum; returns the header.
Header read_header(std::span<const std::uint8_t> bytes, const std::string& source) {
  check_magic<ModelFormatError>(bytes, source, kMagic, "lipdrive model", kModelHeaderSize);
  Header h{};
  h.version = static_cast<std::uint32_t>(get_le(bytes, 8, 4));
  if (h.version != kModelFormatVersion && h.version != kExpressionModelFormatVersion)
    throw ModelFormatError(source + ": unsupported format version " + std::to_string(h.version) +
                           " (this build reads versions " + std::to_string(kModelFormatVersion) + " and " +
                           std::to_string(kExpressionModelFormatVersion) + ")");
  h.vertices = static_cast<std::uint32_t>(get_le(bytes, 12, 4));
  h.components = static_cast<std::uint32_t>(get_le(bytes, 16, 4));
  h.triangles = static_cast<std::uint32_t>(get_le(bytes, 20, 4));
  h.poses = static_cast<std::uint32_t>(get_le(bytes, 24, 4));
  if (h.version == kModelFormatVersion) {
    h.payload_length = get_le(bytes, 28, 8);
    h.checksum = static_cast<std::uint32_t>(get_le(bytes, 36, 4));
    check_payload(bytes, kModelHeaderSize, h, source);
    check_counts(h, h.payload_length, source);
    return h;
  }
  if (bytes.size() < kExpressionModelHeaderSize)
    throw ModelFormatError(source + ": truncated (expected at least " + std::to_string(kExpressionModelHeaderSize) +
                           " header bytes, got " + std::to_string(bytes.size()) + ")");
  h.expressions = static_cast<std::uint32_t>(get_le(bytes, 28, 4));
  h.payload_length = get_le(bytes, 32, 8);
  h.inflated_length = get_le(bytes, 40, 8);
  h.checksum = static_cast<std::uint32_t>(get_le(bytes, 48, 4));
  if (get_le(bytes, 52, 4) != 0) throw ModelFormatError(source + ": the reserved header word is not 0");
  check_payload(bytes, kExpressionModelHeaderSize, h, source);
  check_counts(h, h.inflated_length, source);
  const std::uint64_t most_names = 65537ull * (std::uint64_t{h.poses} + h.expressions);
  if (h.inflated_length > kMaxInflatedModelBytes || h.inflated_length > *fixed_payload_bytes(h) + most_names)
    throw ModelFormatError(source + ": inflated payload length " + std::to_string(h.inflated_length) +
                           " is more than the sizes allow");
  return h;
}

/// The version 2 payload, inflated to exactly h.inflated_length bytes.
std::vector<std::uint8_t> inflate_payload(std::span<const std::uint8_t> stream, const Header& h,
                                          const std::string& source) {
  std::vector<std::uint8_t> inflated(h.inflated_length);
  uLongf inflated_size = static_cast<uLongf>(inflated.size());
  uLong stream_size = static_cast<uLong>(stream.size());
  const int status = ::uncompress2(inflated.data(), &inflated_size, stream.data(), &stream_size);
  if (status != Z_OK || inflated_size != inflated.size() || stream_size != stream.size())
    throw ModelFormatError(source + ": the compressed payload does not inflate to the " +
                           std::to_string(h.inflated_length) + " bytes the header gives (zlib status " +
                           std::to_string(status) + ")");
  return inflated;
}

void require_finite(const float* data, Eigen::Index count, const std::string& source, const char* field) {
  for (Eigen::Index i = 0; i < count; ++i)
    if (!std::isfinite(data[i]))
      throw ModelFormatError(source + ": non-finite number in " + field + " at index " + std::to_string(i));
}

}  // namespace

void validate_model_values(const MorphableModel& m, const std::string& source) {
  if (!std::isfinite(m.total_variance) || m.total_variance < 0)
    throw ModelFormatError(source + ": total_variance is negative or not finite");
  require_finite(m.mean.data(), m.mean.size(), source, "mean");
  require_finite(m.stddev.data(), m.stddev.size(), source, "stddev");
  require_finite(m.basis.data(), m.basis.size(), source, "basis");
  require_finite(m.pose_coefficients.data(), m.pose_coefficients.size(), source, "pose coefficients");
  for (Eigen::Index k = 0; k < m.stddev.size(); ++k)
    if (!(m.stddev[k] > 0))
      throw ModelFormatError(source + ": stddev of component " + std::to_string(k) + " is not positive");

  const auto n = static_cast<std::uint32_t>(m.num_vertices());
  for (std::size_t t = 0; t < m.triangles.size(); ++t)
    for (std::uint32_t v : m.triangles[t])
      if (v >= n)
        throw ModelFormatError(source + ": triangle " + std::to_string(t) + " index " + std::to_string(v) +
                               " out of range (model has " + std::to_string(n) + " vertices)");
  for (int l = 0; l < kNumLandmarks; ++l) {
    const std::int32_t v = m.landmark_vertex[l];
    if (v < -1 || (v >= 0 && static_cast<std::uint32_t>(v) >= n))
      throw ModelFormatError(source + ": landmark " + std::to_string(l) + " vertex " + std::to_string(v) +
                             " out of range (model has " + std::to_string(n) + " vertices, -1 = unmapped)");
  }
  for (std::size_t e = 0; e < m.expression_names.size(); ++e) {
    const std::string& name = m.expression_names[e];
    if (name.empty()) throw ModelFormatError(source + ": expression " + std::to_string(e) + " has no name");
    if (std::find(m.expression_names.begin(), m.expression_names.begin() + e, name) != m.expression_names.begin() + e)
      throw ModelFormatError(source + ": expression name \"" + name + "\" appears twice");
  }
}

std::uint32_t model_format_version(const MorphableModel& model) {
  return model.has_expressions() ? kExpressionModelFormatVersion : kModelFormatVersion;
}

namespace {

/// The header fields both versions start with: magic, version, N, K, T, P.
void write_header_start(ByteWriter& file, const MorphableModel& m, std::uint32_t version) {
  file.bytes(kMagic);
  file.u32(version);
  file.u32(static_cast<std::uint32_t>(m.num_vertices()));
  file.u32(static_cast<std::uint32_t>(m.num_components()));
  file.u32(static_cast<std::uint32_t>(m.triangles.size()));
  file.u32(static_cast<std::uint32_t>(m.pose_names.size()));
}

/// The payload fields both versions share after the basis: triangles, landmarks, poses.
void write_topology_and_poses(ByteWriter& payload, const MorphableModel& m) {
  for (const Triangle& t : m.triangles)
    for (std::uint32_t v : t) payload.u32(v);
  for (std::int32_t v : m.landmark_vertex) payload.i32(v);
  payload.names(m.pose_names);
  payload.floats(m.pose_coefficients.data(), m.pose_coefficients.size());
}

std::vector<std::uint8_t> serialize_pose_model(const MorphableModel& m) {
  ByteWriter payload;
  payload.f32(m.total_variance);
  payload.floats(m.mean.data(), m.mean.size());
  payload.floats(m.stddev.data(), m.stddev.size());
  payload.floats(m.basis.data(), m.basis.size());  // Eigen is column-major
  write_topology_and_poses(payload, m);

  ByteWriter file;
  write_header_start(file, m, kModelFormatVersion);
  file.u64(payload.buffer().size());
  file.u32(crc32(payload.buffer()));
  file.bytes(payload.buffer());
  return std::move(file.buffer());
}

std::vector<std::uint8_t> serialize_expression_model(const MorphableModel& m) {
  ByteWriter payload;
  payload.f32(m.total_variance);
  payload.floats(m.mean.data(), m.mean.size());
  payload.floats(m.stddev.data(), m.stddev.size());
  for (Eigen::Index k = 0; k < m.basis.cols(); ++k) payload.quantized(m.basis.col(k).data(), m.basis.rows());
  write_topology_and_poses(payload, m);
  payload.names(m.expression_names);
  for (Eigen::Index e = 0; e < m.expressions.cols(); ++e)
    payload.quantized(m.expressions.col(e).data(), m.expressions.rows());

  const auto& inflated = payload.buffer();
  std::vector<std::uint8_t> stream(::compressBound(static_cast<uLong>(inflated.size())));
  uLongf stream_size = static_cast<uLongf>(stream.size());
  if (::compress2(stream.data(), &stream_size, inflated.data(), static_cast<uLong>(inflated.size()),
                  Z_BEST_COMPRESSION) != Z_OK)
    throw std::invalid_argument("cannot serialize model: zlib failed to compress the payload");
  stream.resize(stream_size);

  ByteWriter file;
  write_header_start(file, m, kExpressionModelFormatVersion);
  file.u32(static_cast<std::uint32_t>(m.num_expressions()));
  file.u64(stream.size());
  file.u64(inflated.size());
  file.u32(crc32(stream));
  file.u32(0);
  file.bytes(stream);
  return std::move(file.buffer());
}

/// The payload of either version; `in` is the (inflated) payload.
MorphableModel read_payload(ByteReader<ModelFormatError>& in, const Header& h, const std::string& source_name) {
  const Eigen::Index n3 = 3 * Eigen::Index{h.vertices};
  const Eigen::Index k = h.components;
  const bool compact = h.version == kExpressionModelFormatVersion;

  MorphableModel m;
  m.total_variance = in.f32();
  m.mean.resize(n3);
  in.floats(m.mean.data(), static_cast<std::uint64_t>(n3));
  m.stddev.resize(k);
  in.floats(m.stddev.data(), h.components);
  m.basis.resize(n3, k);
  if (compact)
    for (Eigen::Index c = 0; c < k; ++c) in.quantized(m.basis.col(c).data(), n3, "a basis column");
  else
    in.floats(m.basis.data(), static_cast<std::uint64_t>(n3 * k));
  m.triangles.resize(h.triangles);
  for (Triangle& t : m.triangles)
    for (std::uint32_t& v : t) v = in.u32();
  for (std::int32_t& v : m.landmark_vertex) v = in.i32();
  m.pose_names = in.names(h.poses);
  m.pose_coefficients.resize(k, h.poses);
  const auto coefficient_count = static_cast<std::uint64_t>(k) * h.poses;
  if (!compact && in.remaining() != coefficient_count * 4)
    throw ModelFormatError(source_name + ": sizes inconsistent with the payload length (" +
                           std::to_string(in.remaining()) + " bytes left for " + std::to_string(coefficient_count) +
                           " pose coefficients)");
  in.floats(m.pose_coefficients.data(), coefficient_count);
  if (compact) {
    m.expression_names = in.names(h.expressions);
    m.expressions.resize(n3, h.expressions);
    for (Eigen::Index e = 0; e < m.expressions.cols(); ++e)
      in.quantized(m.expressions.col(e).data(), n3, "an expression");
    if (in.remaining() != 0)
      throw ModelFormatError(source_name + ": " + std::to_string(in.remaining()) +
                             " unexpected bytes after the expressions in the inflated payload");
  }
  return m;
}

}  // namespace

std::vector<std::uint8_t> serialize_model(const MorphableModel& m) {
  check_serializable(m);
  return m.has_expressions() ? serialize_expression_model(m) : serialize_pose_model(m);
}

MorphableModel deserialize_model(std::span<const std::uint8_t> bytes, const std::string& source_name) {
  const Header h = read_header(bytes, source_name);
  MorphableModel m;
  if (h.version == kModelFormatVersion) {
    ByteReader<ModelFormatError> in(bytes.subspan(kModelHeaderSize), source_name);
    m = read_payload(in, h, source_name);
  } else {
    const std::vector<std::uint8_t> inflated =
        inflate_payload(bytes.subspan(kExpressionModelHeaderSize), h, source_name);
    ByteReader<ModelFormatError> in(inflated, source_name);
    m = read_payload(in, h, source_name);
  }
  validate_model_values(m, source_name);
  return m;
}

std::uint32_t identity_fingerprint(const MorphableModel& model) {
  std::uint32_t crc = crc_of_floats(0, model.mean.data(), model.mean.size());
  crc = crc_of_floats(crc, model.stddev.data(), model.stddev.size());
  return crc_of_floats(crc, model.basis.data(), model.basis.size());
}

}  // namespace lipdrive
