#include "drivers/osc_receiver.hpp"

#include <lo/lo.h>

#include <cstdint>
#include <cstring>
#include <memory>

namespace lipdrive {
namespace {

/// Argument `i` as a T. liblo's argument pointers point into the message, where OSC aligns
/// arguments to 4 bytes only: reading an 8-byte lo_arg through them is a misaligned access
/// (UndefinedBehaviorSanitizer found it), so the bytes are copied out.
template <class T>
T argument(void* const* argv, int i) {
  T value;
  std::memcpy(&value, argv[i], sizeof value);
  return value;
}

}  // namespace

std::optional<double> OscMessage::number(int i) const {
  if (i < 0 || i >= size()) return std::nullopt;
  switch (types_[static_cast<std::size_t>(i)]) {
    case LO_INT32: return argument<std::int32_t>(argv_, i);
    case LO_INT64: return static_cast<double>(argument<std::int64_t>(argv_, i));
    case LO_FLOAT: return argument<float>(argv_, i);
    case LO_DOUBLE: return argument<double>(argv_, i);
    case LO_TRUE: return 1.0;
    case LO_FALSE: return 0.0;
    default: return std::nullopt;
  }
}

std::optional<std::string_view> OscMessage::string(int i) const {
  if (i < 0 || i >= size()) return std::nullopt;
  const char type = types_[static_cast<std::size_t>(i)];
  if (type != LO_STRING && type != LO_SYMBOL) return std::nullopt;
  return std::string_view(static_cast<const char*>(argv_[i]));
}

OscReceiver::OscReceiver(const std::string& host, int port)
    : socket_(UdpSocket::bound(resolve_udp(host, port))), local_(socket_.local()) {}

int OscReceiver::port() const {
  const sockaddr_storage& a = local_.address;
  if (a.ss_family == AF_INET) return ntohs(reinterpret_cast<const sockaddr_in*>(&a)->sin_port);
  return ntohs(reinterpret_cast<const sockaddr_in6*>(&a)->sin6_port);
}

OscReceiver::Received OscReceiver::receive(std::chrono::milliseconds timeout,
                                           const std::function<void(const OscMessage&)>& handle, std::string* from) {
  UdpEndpoint sender;
  const std::size_t size = socket_.receive(buffer_, timeout, &sender);
  if (size == 0) return Received::kNothing;
  if (from) *from = sender.describe();
  if (size > buffer_.size()) return Received::kMalformed;
  if (size >= 8 && std::memcmp(buffer_.data(), "#bundle", 8) == 0) return Received::kBundle;
  int result = 0;
  const std::unique_ptr<void, void (*)(void*)> message(lo_message_deserialise(buffer_.data(), size, &result),
                                                       [](void* m) { lo_message_free(m); });
  if (!message || result != 0) return Received::kMalformed;
  OscMessage view;
  view.address_ = lo_get_path(buffer_.data(), static_cast<ssize_t>(size));
  const char* types = lo_message_get_types(message.get());
  view.types_ = types ? std::string_view(types) : std::string_view();
  if (!view.types_.empty() && view.types_.front() == ',') view.types_.remove_prefix(1);
  view.argv_ = reinterpret_cast<void* const*>(lo_message_get_argv(message.get()));
  handle(view);
  return Received::kMessage;
}

}  // namespace lipdrive
