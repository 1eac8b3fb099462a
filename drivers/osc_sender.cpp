#include "drivers/osc_sender.hpp"

#include <lo/lo.h>

#include <cstring>
#include <memory>
#include <stdexcept>

namespace lipdrive {
namespace {

constexpr std::int64_t kNsPerSecond = 1'000'000'000;
// Seconds from 1900-01-01 (NTP) to 1970-01-01 (Unix).
constexpr std::int64_t kNtpToUnixSeconds = 2'208'988'800;
// IPv4's largest UDP payload.
constexpr std::size_t kMaxDatagram = 65'507;
// "#bundle\0", then the time tag (OSC 1.0, "OSC Bundles").
constexpr std::size_t kTimeTagOffset = 8, kFirstElementOffset = 16;

/// The bytes an argument takes: 4 for a number, a string with its NUL padded to 4.
std::size_t argument_size(const OscBundle::Message& m) {
  return m.type == OscBundle::Type::kString ? (m.string_length / 4 + 1) * 4 : 4;
}

void put_big_endian(std::uint8_t* at, std::uint32_t value) {
  at[0] = static_cast<std::uint8_t>(value >> 24);
  at[1] = static_cast<std::uint8_t>(value >> 16);
  at[2] = static_cast<std::uint8_t>(value >> 8);
  at[3] = static_cast<std::uint8_t>(value);
}

}  // namespace

OscTimeTag osc_time_tag(std::int64_t unix_time_ns) {
  const std::int64_t seconds = unix_time_ns / kNsPerSecond, rest = unix_time_ns % kNsPerSecond;
  return {static_cast<std::uint32_t>(seconds + kNtpToUnixSeconds),
          static_cast<std::uint32_t>((static_cast<std::uint64_t>(rest) << 32) / kNsPerSecond)};
}

OscBundle::OscBundle(std::span<const Message> messages) : messages_(messages.begin(), messages.end()) {
  const std::unique_ptr<std::remove_pointer_t<lo_bundle>, void (*)(lo_bundle)> bundle(lo_bundle_new(LO_TT_IMMEDIATE),
                                                                                      lo_bundle_free_recursive);
  std::size_t offset = kFirstElementOffset;
  for (const Message& m : messages_) {
    lo_message message = lo_message_new();
    if (m.type == Type::kInt32) lo_message_add_int32(message, 0);
    if (m.type == Type::kFloat) lo_message_add_float(message, 0);
    if (m.type == Type::kString) lo_message_add_string(message, std::string(m.string_length, ' ').c_str());
    lo_bundle_add_message(bundle.get(), m.address.c_str(), message);
    // Each element: its size (int32), then the message, whose argument comes last.
    offset += 4 + lo_message_length(message, m.address.c_str());
    argument_offsets_.push_back(offset - argument_size(m));
  }
  const std::size_t length = lo_bundle_length(bundle.get());
  if (length > kMaxDatagram)
    throw std::invalid_argument("an OSC bundle of " + std::to_string(length) + " bytes does not fit in a datagram");
  if (length != offset) throw std::logic_error("liblo laid the OSC bundle out unexpectedly");
  bytes_.resize(length);
  std::size_t written = 0;
  lo_bundle_serialise(bundle.get(), bytes_.data(), &written);
}

void OscBundle::set_time_tag(OscTimeTag time_tag) {
  put_big_endian(&bytes_[kTimeTagOffset], time_tag.seconds);
  put_big_endian(&bytes_[kTimeTagOffset + 4], time_tag.fraction);
}

void OscBundle::set(std::size_t index, float value) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  put_big_endian(&bytes_[argument_offsets_[index]], bits);
}

void OscBundle::set(std::size_t index, std::int32_t value) {
  put_big_endian(&bytes_[argument_offsets_[index]], static_cast<std::uint32_t>(value));
}

void OscBundle::set(std::size_t index, std::string_view value) {
  const Message& m = messages_[index];
  std::uint8_t* at = &bytes_[argument_offsets_[index]];
  // The layout is fixed: a shorter value is padded with spaces, a longer one cut.
  const std::size_t n = std::min(value.size(), m.string_length);
  std::memcpy(at, value.data(), n);
  std::memset(at + n, ' ', m.string_length - n);
  std::memset(at + m.string_length, 0, argument_size(m) - m.string_length);
}

OscSender::OscSender(const std::string& host, int port)
    : destination_(resolve_udp(host, port)), socket_(UdpSocket::for_sending(destination_)) {}

bool OscSender::send(const OscBundle& bundle) { return socket_.send_to(bundle.bytes(), destination_); }

}  // namespace lipdrive
