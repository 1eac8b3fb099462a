#include "drivers/osc_receiver.hpp"

#include <lo/lo.h>

#include <cstring>
#include <memory>

namespace lipdrive {
namespace {

const lo_arg* argument(void* const* argv, int i) { return static_cast<const lo_arg*>(argv[i]); }

}  // namespace

std::optional<double> OscMessage::number(int i) const {
  if (i < 0 || i >= size()) return std::nullopt;
  const lo_arg* arg = argument(argv_, i);
  switch (types_[static_cast<std::size_t>(i)]) {
    case LO_INT32: return arg->i;
    case LO_INT64: return static_cast<double>(arg->h);
    case LO_FLOAT: return arg->f;
    case LO_DOUBLE: return arg->d;
    case LO_TRUE: return 1.0;
    case LO_FALSE: return 0.0;
    default: return std::nullopt;
  }
}

std::optional<std::string_view> OscMessage::string(int i) const {
  if (i < 0 || i >= size()) return std::nullopt;
  const char type = types_[static_cast<std::size_t>(i)];
  if (type != LO_STRING && type != LO_SYMBOL) return std::nullopt;
  return std::string_view(&argument(argv_, i)->s);
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
