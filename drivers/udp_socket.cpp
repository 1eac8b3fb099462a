#include "drivers/udp_socket.hpp"

#include <fmt/format.h>

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <poll.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace lipdrive {
namespace {

UniqueFd open_socket(const UdpEndpoint& endpoint) {
  UniqueFd fd(::socket(endpoint.address.ss_family, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0));
  if (!fd.valid()) throw UdpError("udp " + endpoint.describe() + ": cannot create a socket: " + std::strerror(errno));
  return fd;
}

}  // namespace

std::string UdpEndpoint::describe() const {
  char host[INET6_ADDRSTRLEN] = "?";
  int port = 0;
  if (address.ss_family == AF_INET) {
    const auto* in = reinterpret_cast<const sockaddr_in*>(&address);
    ::inet_ntop(AF_INET, &in->sin_addr, host, sizeof host);
    port = ntohs(in->sin_port);
    return fmt::format("{}:{}", host, port);
  }
  if (address.ss_family == AF_INET6) {
    const auto* in6 = reinterpret_cast<const sockaddr_in6*>(&address);
    ::inet_ntop(AF_INET6, &in6->sin6_addr, host, sizeof host);
    port = ntohs(in6->sin6_port);
  }
  return fmt::format("[{}]:{}", host, port);
}

UdpEndpoint resolve_udp(const std::string& host, int port) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  hints.ai_flags = AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  if (const int error = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found); error != 0)
    throw UdpError("host \"" + host + "\" does not resolve: " + ::gai_strerror(error), error == EAI_AGAIN);
  const addrinfo& chosen = preferred_address(*found);
  UdpEndpoint endpoint;
  std::memcpy(&endpoint.address, chosen.ai_addr, chosen.ai_addrlen);
  endpoint.length = chosen.ai_addrlen;
  ::freeaddrinfo(found);
  return endpoint;
}

const addrinfo& preferred_address(const addrinfo& found) {
  for (const addrinfo* a = &found; a != nullptr; a = a->ai_next)
    if (a->ai_family == AF_INET) return *a;
  return found;
}

UdpSocket UdpSocket::for_sending(const UdpEndpoint& destination) { return UdpSocket(open_socket(destination)); }

UdpSocket UdpSocket::bound(const UdpEndpoint& local) {
  UdpSocket socket(open_socket(local));
  if (::bind(socket.fd_.get(), reinterpret_cast<const sockaddr*>(&local.address), local.length) != 0)
    throw UdpError("udp " + local.describe() + ": cannot bind: " + std::strerror(errno));
  return socket;
}

bool UdpSocket::send_to(std::span<const std::uint8_t> datagram, const UdpEndpoint& destination) const {
  const ssize_t sent = ::sendto(fd_.get(), datagram.data(), datagram.size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                                reinterpret_cast<const sockaddr*>(&destination.address), destination.length);
  return sent == static_cast<ssize_t>(datagram.size());
}

std::size_t UdpSocket::receive(std::span<std::uint8_t> buffer, std::chrono::milliseconds timeout,
                               UdpEndpoint* from) const {
  pollfd readable{fd_.get(), POLLIN, 0};
  if (::poll(&readable, 1, static_cast<int>(timeout.count())) <= 0) return 0;
  UdpEndpoint sender;
  sender.length = sizeof sender.address;
  const ssize_t size = ::recvfrom(fd_.get(), buffer.data(), buffer.size(), MSG_DONTWAIT | MSG_TRUNC,
                                  reinterpret_cast<sockaddr*>(&sender.address), &sender.length);
  if (size <= 0) return 0;
  if (from) *from = sender;
  return static_cast<std::size_t>(size);
}

UdpEndpoint UdpSocket::local() const {
  UdpEndpoint endpoint;
  endpoint.length = sizeof endpoint.address;
  ::getsockname(fd_.get(), reinterpret_cast<sockaddr*>(&endpoint.address), &endpoint.length);
  return endpoint;
}

}  // namespace lipdrive
