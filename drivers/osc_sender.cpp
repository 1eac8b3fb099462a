#include "drivers/osc_sender.hpp"

#include <lo/lo.h>

#include <cerrno>

namespace lipdrive {
namespace {

constexpr std::int64_t kNsPerSecond = 1'000'000'000;
// Seconds from 1900-01-01 (NTP) to 1970-01-01 (Unix).
constexpr std::int64_t kNtpToUnixSeconds = 2'208'988'800;
// IPv4's largest UDP payload.
constexpr std::size_t kMaxDatagram = 65'507;

}  // namespace

OscTimeTag osc_time_tag(std::int64_t unix_time_ns) {
  const std::int64_t seconds = unix_time_ns / kNsPerSecond, rest = unix_time_ns % kNsPerSecond;
  return {static_cast<std::uint32_t>(seconds + kNtpToUnixSeconds),
          static_cast<std::uint32_t>((static_cast<std::uint64_t>(rest) << 32) / kNsPerSecond)};
}

OscSender::OscSender(const std::string& host, int port)
    : destination_(resolve_udp(host, port)), socket_(UdpSocket::for_sending(destination_)), buffer_(kMaxDatagram) {}

OscSender::~OscSender() {
  if (bundle_) lo_bundle_free_recursive(bundle_);
}

void OscSender::begin_bundle(OscTimeTag time_tag) {
  if (bundle_) lo_bundle_free_recursive(bundle_);
  bundle_ = lo_bundle_new(lo_timetag{time_tag.seconds, time_tag.fraction});
}

void OscSender::add(const char* address, float value) {
  lo_message message = lo_message_new();
  lo_message_add_float(message, value);
  lo_bundle_add_message(bundle_, address, message);
}

void OscSender::add(const char* address, std::int32_t value) {
  lo_message message = lo_message_new();
  lo_message_add_int32(message, value);
  lo_bundle_add_message(bundle_, address, message);
}

void OscSender::add(const char* address, const char* value) {
  lo_message message = lo_message_new();
  lo_message_add_string(message, value);
  lo_bundle_add_message(bundle_, address, message);
}

bool OscSender::send_bundle() {
  if (!bundle_) return false;
  const std::size_t size = lo_bundle_length(bundle_);
  last_size_ = size;
  if (size > buffer_.size()) {
    errno = EMSGSIZE;
    return false;
  }
  std::size_t written = 0;
  if (!lo_bundle_serialise(bundle_, buffer_.data(), &written)) return false;
  return socket_.send_to({buffer_.data(), written}, destination_);
}

}  // namespace lipdrive
